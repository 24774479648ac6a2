"""Milliseconds per control step of each aerobench env against the bare PhysX step of the same scene.

Rows (one env, physx_cpu unless a GPU is named): (a) the bare scene, 12 PhysX steps with the hover joint efforts
held constant (no controller, no aerobench code); (b) ManiSkill's PickCube-v1, state, as a reference; (c)
AeroFly-v1; (d) AeroPick-v1 and AeroPlace-v1, state, hovering and with the privileged expert acting; (e) the same
Pick env with the three 128x128 RGB-D cameras (lavapipe's cost: reported, kept out of the ratios). Each aerobench
row's ratio is to the bare step of its own scene. Then expert Pick episodes per minute on one core, and `aerobench
train ppo` env steps per second (Pick, from scratch, the spec's 64-step windows) with K = 1 env and with K = 2
worker processes (physx_cpu runs one env per process).

    python bench/step_cost.py [--steps 100] [--episodes 5] [--ppo-windows 3] [--ppo-envs 2] [--no-cameras] [--repeats 1]
"""

from __future__ import annotations

import argparse
import logging
import os
import time

os.environ.setdefault("MS_SKIP_ASSET_DOWNLOAD_PROMPT", "1")
logging.getLogger("mani_skill").setLevel(logging.ERROR)

import gymnasium as gym  # noqa: E402
import torch  # noqa: E402

import aerobench.envs  # noqa: E402,F401
from aerobench.envs.platforms import CONTROL_HZ, PHYSICS_HZ  # noqa: E402
from aerobench.policies import make_policy  # noqa: E402

SUBSTEPS = PHYSICS_HZ // CONTROL_HZ
SEED = 0


REPEATS = 1  # timings per row; the row reports their minimum (--repeats: other load can only add time)


def per_step_ms(fn, steps: int, warmup: int = 5) -> float:
    """ms per step of `fn(n)`, which runs n steps and may return the seconds they took (leaving out what is not a
    step, e.g. a reset); else its wall time counts."""
    fn(warmup)
    best = float("inf")
    for _ in range(REPEATS):
        t0 = time.perf_counter()
        spent = fn(steps)
        best = min(best, ((time.perf_counter() - t0) if spent is None else spent) / steps * 1e3)
    return best


def bare_physics_ms(base, steps: int) -> float:
    """12 PhysX steps of the env's own scene, the airframe's joint efforts frozen at their current (hover) values."""
    agent, px = base.agent, base.scene.px
    qf = agent.robot.get_qf().clone()

    def bare(n):
        for _ in range(n * SUBSTEPS):
            agent.robot.set_qf(qf)
            px.step()

    return per_step_ms(bare, steps)


def aero_rows(env_id: str, steps: int, expert: bool, **kwargs) -> tuple[float, float]:
    """(ms per env.step, ms per bare step of the same scene); with `expert`, the expert's act() is in the step."""
    env = gym.make(env_id, num_envs=1, **kwargs)
    obs, _ = env.reset(seed=SEED, options={"reconfigure": True})
    base = env.unwrapped
    hover = torch.zeros(1, base.platform.action_dim)
    hover[:, -1] = -1.0 if env_id == "AeroPlace-v1" else 1.0  # Place starts holding the object: keep it
    state = {"obs": obs, "policy": make_policy("expert", base) if expert else None}
    if expert:
        state["policy"].reset(torch.arange(1))

    def ours(n) -> float:
        spent = 0.0
        for _ in range(n):
            t0 = time.perf_counter()
            policy = state["policy"]
            action = policy.act(state["obs"]) if policy is not None else hover
            state["obs"], _, terminated, truncated, _ = env.step(action)
            spent += time.perf_counter() - t0
            if bool(terminated.any() | truncated.any()):  # a reset is not a control step: not timed
                state["obs"], _ = env.reset(seed=SEED)
                if expert:  # as the rollout runner: a policy per episode (the reset rebuilt the scene's evaluators)
                    state["policy"] = make_policy("expert", base)
                    state["policy"].reset(torch.arange(1))
        return spent

    t_ours = per_step_ms(ours, steps)
    t_bare = bare_physics_ms(base, steps)
    env.close()
    return t_ours, t_bare


def maniskill_reference_ms(steps: int) -> float:
    env = gym.make("PickCube-v1", obs_mode="state", num_envs=1)
    env.reset(seed=SEED)
    action = torch.zeros(env.action_space.shape)

    def ours(n):
        for _ in range(n):
            env.step(action)

    t = per_step_ms(ours, steps)
    env.close()
    return t


def reset_ms(resets: int = 15) -> float:
    """Median time of an AeroPick-v1 reset with a new layout (what every episode of generation and PPO pays)."""
    env = gym.make("AeroPick-v1", obs_mode="state_dict", num_envs=1)
    env.reset(seed=SEED, options={"reconfigure": True})
    times = []
    for i in range(1, resets + 1):
        t0 = time.perf_counter()
        env.reset(seed=SEED + i, options={"reconfigure": True})
        times.append((time.perf_counter() - t0) * 1e3)
    env.close()
    return sorted(times)[len(times) // 2]


def expert_episodes_per_min(episodes: int) -> tuple[float, int, int]:
    """Expert Pick episodes (TidyHouse, state) run to their end, one after another in this process."""
    env = gym.make("AeroPick-v1", obs_mode="state_dict", num_envs=1)
    base = env.unwrapped
    successes = steps_total = 0
    t0 = time.perf_counter()
    for i in range(episodes):
        obs, _ = env.reset(seed=1000 + i, options={"reconfigure": True})
        policy = make_policy("expert", base)  # after the reset, as the rollout runner does: it plans in this layout
        policy.reset(torch.arange(1))
        while True:
            obs, _, terminated, truncated, info = env.step(policy.act(obs))
            steps_total += 1
            if bool(terminated.any() | truncated.any()):
                successes += int(info["success"][0])
                break
    minutes = (time.perf_counter() - t0) / 60
    env.close()
    return episodes / minutes, successes, steps_total


def ppo_steps_per_second(num_envs: int, windows: int) -> float:
    """Env steps per second of `train_ppo` over its windows after the first (which pays the process start-up)."""
    import tempfile

    from aerobench.train.common import read_scalars
    from aerobench.train.ppo import PPOConfig, train_ppo

    with tempfile.TemporaryDirectory() as out:
        config = PPOConfig(setting="TidyHouse", skill="pick", objects=("master_chef_can",), out=out, num_envs=num_envs,
                           total_steps=64 * num_envs * windows, hidden=(64, 64), save_every=windows, progress=False)
        train_ppo(config)
        sps = [v for _, v in read_scalars(out, "charts/SPS")][1:]
    return sum(sps) / len(sps)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=100, help="control steps timed per row")
    parser.add_argument("--episodes", type=int, default=5, help="expert Pick episodes for the episodes-per-minute row")
    parser.add_argument("--ppo-windows", type=int, default=3, help="PPO windows per K (0: skip the PPO rows)")
    parser.add_argument("--ppo-envs", type=lambda t: [int(v) for v in t.split(",")], default=[2],
                        help="K values (> 1) of the worker-process PPO rows, comma-separated")
    parser.add_argument("--no-cameras", action="store_true", help="skip the rendered row (e)")
    parser.add_argument("--repeats", type=int, default=1,
                        help="time each row this many times and report the minimum (on a shared machine)")
    args = parser.parse_args()
    global REPEATS
    REPEATS = max(1, args.repeats)
    torch.set_num_threads(1)
    print(f"physx_cpu, one env, one torch thread, {SUBSTEPS} physics steps per control step, {args.steps} control "
          f"steps per row")
    print(f"{'row':<44} {'ms/step':>9} {'bare ms':>9} {'ratio':>7}")
    reference = maniskill_reference_ms(args.steps)
    print(f"{'(b) ManiSkill PickCube-v1, state':<44} {reference:9.2f} {'':>9} {'':>7}")
    rows = [
        ("(c) AeroFly-v1, state, hovering", "AeroFly-v1", False, {"obs_mode": "state_dict"}),
        ("(d) AeroPick-v1, state, hovering", "AeroPick-v1", False, {"obs_mode": "state_dict"}),
        ("(d) AeroPick-v1, state, expert acting", "AeroPick-v1", True, {"obs_mode": "state_dict"}),
        ("(d) AeroPlace-v1, state, hovering", "AeroPlace-v1", False, {"obs_mode": "state_dict"}),
        ("(d) AeroPlace-v1, state, expert acting", "AeroPlace-v1", True, {"obs_mode": "state_dict"}),
    ]
    if not args.no_cameras:
        rows.append(("(e) AeroPick-v1, 3 RGB-D cameras, expert", "AeroPick-v1", True, {"obs_mode": "rgbd"}))
    for label, env_id, expert, kwargs in rows:
        steps = args.steps if kwargs["obs_mode"] != "rgbd" else max(args.steps // 5, 5)
        ours, bare = aero_rows(env_id, steps, expert, **kwargs)
        print(f"{label:<44} {ours:9.2f} {bare:9.2f} {ours / bare:6.1f}x", flush=True)
    print("(a) is each row's 'bare ms': the same scene's 12 PhysX steps alone. Goals: Pick with the expert <= 3x, "
          "Fly <= 1.5x")
    print(f"AeroPick-v1 reset with a new layout: {reset_ms():.0f} ms (median of 15)")
    rate, successes, steps = expert_episodes_per_min(args.episodes)
    print(f"expert Pick episodes per minute on one core: {rate:.1f} ({successes}/{args.episodes} successful, "
          f"{steps} control steps)")
    if args.ppo_windows >= 2:
        one = ppo_steps_per_second(1, args.ppo_windows)
        print(f"train ppo env steps per second: K=1 {one:.1f}")
        for k in args.ppo_envs:
            sps = ppo_steps_per_second(k, args.ppo_windows)
            print(f"train ppo env steps per second: K={k} worker processes {sps:.1f} ({sps / one:.2f}x of K=1"
                  + ("; goal >= 1.8x on 2 cores)" if k == 2 else ")"), flush=True)


if __name__ == "__main__":
    main()
