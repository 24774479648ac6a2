"""The least a control step can cost on physx_cpu with a feedback controller in Python, against what it costs.

`bench/step_cost.py` compares each env's control step with the bare PhysX step of its scene. This script asks how
far down the step could go at all, one env, physx_cpu, state only, hovering. In one run, in milliseconds per control
step (12 physics steps at 240 Hz), each variant timed in short windows from the same saved state, interleaved:

- bare: PhysX alone, the airframe's joint efforts held (`set_qf` and `step`, 12 times);
- + state reads: and the joint positions and velocities read before each physics step, as any feedback controller
  must (what the flight controller reads, nothing computed from them);
- ManiSkill's step(): `env.step` with every aerobench hook a no-op (the efforts held, the action ignored, the
  observation, signals and reward cached): ManiSkill's own machinery around the same 12 physics steps;
- + the flight controller: bare with the real controller before each physics step (reads, one compiled call,
  writes);
- the whole step: `env.step` as it runs.

The floor is bare + the state reads' cost + ManiSkill's step()'s cost: a step with a controller, an observation and
an evaluation that cost nothing would still cost that. Its ratio to bare says which ratio goals this architecture can
reach on a CPU.

    python bench/step_floor.py [--envs AeroFly-v1,AeroPick-v1] [--windows 30] [--steps 20]
"""

from __future__ import annotations

import argparse
import logging
import os
import time
from collections.abc import Callable

os.environ.setdefault("MS_SKIP_ASSET_DOWNLOAD_PROMPT", "1")
logging.getLogger("mani_skill").setLevel(logging.ERROR)

import gymnasium as gym  # noqa: E402
import torch  # noqa: E402

import aerobench.envs  # noqa: E402,F401
from aerobench.envs.platforms import CONTROL_HZ, PHYSICS_HZ  # noqa: E402

SUBSTEPS = PHYSICS_HZ // CONTROL_HZ
SEED = 0
BARE, READS, MANISKILL, CONTROLLER, WHOLE = (
    "bare", "+ state reads", "ManiSkill's step()", "+ the flight controller", "the whole step")
FLOOR = "floor (bare + reads + ManiSkill)"


def variants(env, hover: torch.Tensor) -> dict[str, Callable[[int], None]]:
    """Each variant as a function that runs n control steps."""
    base = env.unwrapped
    controller, px = base.agent.body_controller, base.scene.px
    articulation = controller._cpu_articulation
    held = articulation.get_qf().copy()
    _, _, _, _, info = env.step(hover)
    raw_obs = base.get_obs(info, unflattened=True)
    reward = base.get_reward(obs=raw_obs, action=hover, info=info)

    def bare(n):
        for _ in range(n * SUBSTEPS):
            articulation.set_qf(held)
            px.step()

    def reads(n):
        for _ in range(n * SUBSTEPS):
            torch.from_numpy(articulation.get_qpos()[None]), torch.from_numpy(articulation.get_qvel()[None])
            articulation.set_qf(held)
            px.step()

    def with_controller(n):
        for _ in range(n * SUBSTEPS):
            controller.before_simulation_step()
            px.step()

    hooks = {  # (owner, name, no-op): instance attributes, removed again after each window
        (base.agent, "before_simulation_step"): lambda: articulation.set_qf(held),
        (base.agent, "set_action"): lambda action: None,
        (base, "evaluate"): lambda: info,
        (base, "get_obs"): lambda *args, **kwargs: raw_obs,
        (base, "get_reward"): lambda *args, **kwargs: reward,
        (base, "_before_control_step"): lambda: None,
        (base, "_after_control_step"): lambda: None,
    }

    def maniskill(n):
        for (owner, name), fn in hooks.items():
            setattr(owner, name, fn)
        try:
            for _ in range(n):
                env.step(hover)
        finally:
            for owner, name in hooks:
                del owner.__dict__[name]

    def whole(n):
        for _ in range(n):
            env.step(hover)

    return {BARE: bare, READS: reads, MANISKILL: maniskill, CONTROLLER: with_controller, WHOLE: whole}


def floor_row(env_id: str, windows: int, steps: int) -> dict[str, float]:
    """ms per control step of each variant (the minimum over `windows` windows of `steps` control steps, each from
    the same saved state)."""
    env = gym.make(env_id, num_envs=1, obs_mode="state")
    base = env.unwrapped
    env.reset(seed=SEED, options={"reconfigure": True})
    hover = torch.zeros(1, base.platform.action_dim)
    hover[:, -1] = 1.0  # the gripper held open
    for _ in range(10):  # lift-off transients out, the compiled kernels loaded
        env.step(hover)
    state = base.get_state_dict()
    runs = variants(env, hover)
    best = {name: float("inf") for name in runs}
    for _ in range(windows):
        for name, run in runs.items():
            base.set_state_dict(state)
            t0 = time.perf_counter()
            run(steps)
            best[name] = min(best[name], (time.perf_counter() - t0) / steps * 1e3)
    env.close()
    return best


def floor_ms(row: dict[str, float]) -> float:
    """bare + what the state reads add + what ManiSkill's step() adds."""
    return row[READS] + row[MANISKILL] - row[BARE]


def main(argv: list[str] | None = None) -> dict[str, dict[str, float]]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--envs", default="AeroFly-v1,AeroPick-v1")
    parser.add_argument("--windows", type=int, default=30, help="timed windows per variant (the minimum is kept)")
    parser.add_argument("--steps", type=int, default=20, help="control steps per window")
    args = parser.parse_args(argv)
    if args.windows < 1 or args.steps < 1:
        parser.error("--windows and --steps must be positive integers")
    torch.set_num_threads(1)
    rows = {env_id: floor_row(env_id, args.windows, args.steps) for env_id in args.envs.split(",")}
    print(f"physx_cpu, one env, state, hovering; ms per control step ({SUBSTEPS} physics steps), ratio to bare; "
          f"minimum of {args.windows} windows of {args.steps} control steps")
    for env_id, row in rows.items():
        print(f"{env_id}")
        for name, ms in row.items():
            print(f"  {name:<34} {ms:7.3f} ms {ms / row[BARE]:6.2f}x")
        floor = floor_ms(row)
        print(f"  {FLOOR:<34} {floor:7.3f} ms {floor / row[BARE]:6.2f}x")
    return rows


if __name__ == "__main__":
    main()
