"""Where one control step of an aerobench env goes: microseconds per control step by part, in one run.

`bench/step_cost.py` gives each env's control step against the bare PhysX step of its scene; this script splits the
step itself (one env, physx_cpu, state only), timing each part where the env calls it:

- PhysX: the 12 `scene.step()` calls of a control step;
- flight controller: the agent's `before_simulation_step` before each of them (joints in, fused law, efforts out);
- action: `agent.set_action` (our checks, ManiSkill's combined controller, the gripper's drive targets);
- `evaluate()` (once per control step; later calls return the cached signals), with inside it the step context
  (the step's reads, among them the contact read, and the shared signals computed from them: airframe state, tool
  centre point, grasp checks, flight envelope, the airframe's clearance; one compiled call on a CPU);
- observation: `get_obs`; the expert: `policy.act` (on the cached step context);
- the rest: ManiSkill's `step()` plumbing and our hooks around it (the total minus the top-level parts above).

    python bench/step_breakdown.py [--env AeroPick-v1] [--steps 300] [--hover]
"""

from __future__ import annotations

import argparse
import logging
import os
import time
from collections import defaultdict

os.environ.setdefault("MS_SKIP_ASSET_DOWNLOAD_PROMPT", "1")
logging.getLogger("mani_skill").setLevel(logging.ERROR)

import gymnasium as gym  # noqa: E402
import torch  # noqa: E402

import aerobench.envs  # noqa: E402,F401
from aerobench.policies import make_policy  # noqa: E402

SEED = 0
ACTION, CONTROLLER, PHYSX = "action", "flight controller (12 calls)", "PhysX (12 steps)"
EVALUATE, CONTEXT = "evaluate()", "  of which the step context"
CONTACTS, SIGNALS = "    of which the contact read", "    of which the shared signals"
OBSERVATION, EXPERT = "observation", "expert (on the cached context)"
PARTS = (ACTION, CONTROLLER, PHYSX, EVALUATE, CONTEXT, CONTACTS, SIGNALS, OBSERVATION, EXPERT)


def timed(owner, name: str, label: str, spent: dict[str, float]) -> None:
    """Replace `owner.name` by a wrapper that adds its wall time to `spent[label]` (an instance attribute: the
    class and every other env are untouched)."""
    fn = getattr(owner, name)

    def wrapper(*args, **kwargs):
        t0 = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            spent[label] += time.perf_counter() - t0

    setattr(owner, name, wrapper)


def instrument(base, policy, spent: dict[str, float]) -> None:
    """Time the parts of `base`'s step (and `policy.act`) into `spent`. A reset that rebuilds the scene (one CPU env
    gets a new layout per episode) brings a new agent, scene, contact reader and evaluators: instrument again."""
    timed(base.agent, "set_action", ACTION, spent)
    timed(base.agent, "before_simulation_step", CONTROLLER, spent)
    timed(base.scene, "step", PHYSX, spent)
    timed(base, "evaluate", EVALUATE, spent)
    if hasattr(base, "step_context"):
        timed(base, "step_context", CONTEXT, spent)
        timed(base.contacts, "read", CONTACTS, spent)
        if hasattr(base, "_signals_kernel"):  # (an older tree, for before/after runs, has none)
            timed(base, "_signals_kernel", SIGNALS, spent)
    timed(base, "get_obs", OBSERVATION, spent)
    if policy is not None:
        timed(policy, "act", EXPERT, spent)


def breakdown(env_id: str, steps: int, expert: bool) -> tuple[float, dict[str, float]]:
    """(microseconds per control step, {part: microseconds per control step})."""
    env = gym.make(env_id, num_envs=1, obs_mode="state")
    base = env.unwrapped
    hover = torch.zeros(1, base.platform.action_dim)
    hover[:, -1] = -1.0 if env_id == "AeroPlace-v1" else 1.0
    spent: dict[str, float] = defaultdict(float)
    obs, policy = None, None

    def reset() -> None:
        nonlocal obs, policy
        for name in ("evaluate", "step_context", "_signals_kernel", "get_obs"):  # the env's own: unwrap before reset
            base.__dict__.pop(name, None)
        obs, _ = env.reset(seed=SEED, options={"reconfigure": True})
        policy = make_policy("expert", base) if expert else None  # as the rollout runner: a policy per episode
        if policy is not None:
            policy.reset(torch.arange(1))
        instrument(base, policy, spent)

    def run(n: int) -> float:
        nonlocal obs
        total = 0.0
        for _ in range(n):
            t0 = time.perf_counter()
            obs, _, terminated, truncated, _ = env.step(policy.act(obs) if policy is not None else hover)
            total += time.perf_counter() - t0
            if bool(terminated.any() | truncated.any()):  # a reset is not a control step: its parts are not counted
                kept = dict(spent)
                reset()
                spent.clear()
                spent.update(kept)
        return total

    reset()
    run(10)  # warm-up (the compiled kernels load, caches fill)
    spent.clear()
    total = run(steps)
    env.close()
    return total / steps * 1e6, {k: v / steps * 1e6 for k, v in spent.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="AeroPick-v1")
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--hover", action="store_true", help="hover instead of the expert acting")
    args = parser.parse_args()
    if args.env == "AeroFly-v1" and not args.hover:
        parser.error("AeroFly-v1 (the flight test) has no expert: pass --hover")
    torch.set_num_threads(1)
    total, parts = breakdown(args.env, args.steps, expert=not args.hover)
    who = "hovering" if args.hover else "expert acting"
    print(f"{args.env}, state, {who}, physx_cpu, one env, one torch thread, {args.steps} control steps")
    print(f"{'part':<36} {'us/step':>9} {'share':>7}")
    top = 0.0
    for label in PARTS:
        if label in parts:
            print(f"{label:<36} {parts[label]:9.0f} {parts[label] / total:6.1%}")
            top += 0.0 if label.startswith(" ") else parts[label]
    print(f"{'the rest (step plumbing, checks)':<36} {total - top:9.0f} {(total - top) / total:6.1%}")
    print(f"{'control step':<36} {total:9.0f} {1:6.1%}")


if __name__ == "__main__":
    main()
