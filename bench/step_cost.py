"""Milliseconds per control step of each aerobench env against the bare PhysX step of the same scene.

Rows (one env, physx_cpu unless a GPU is named): (a) the bare scene, 12 PhysX steps per control step with no
controller and no aerobench code, two ways: at rest (the scene after the row, the joint efforts frozen) and the row's
own episode replayed (the efforts and gripper targets it recorded, so the same states, contacts and sleeping bodies);
(b) ManiSkill's PickCube-v1, state, as a reference (against its own bare physics steps); (c)
AeroFly-v1; (d) AeroPick-v1 and AeroPlace-v1, state, hovering and with the privileged expert acting; (e) the same
Pick env with the three 128x128 RGB-D cameras (lavapipe's cost: reported, kept out of the ratios). Each aerobench
row's ratios are to the bare steps of its own scene; with `--repeats`, the row's episode and its replay are timed in
turn, the minimum of each kept. Then expert Pick episodes per minute on one core, and `aerobench
train ppo` env steps per second (Pick, from scratch, the spec's 64-step windows) with K = 1 env and with K = 2
worker processes (physx_cpu runs one env per process), the K's in turn for `--ppo-repeats` rounds, the best of each
kept. A first line says how this host prices a call after a pause (`bench/call_warmth.py`), which moves every ratio.

    python bench/step_cost.py [--steps 100] [--episodes 5] [--ppo-windows 8] [--ppo-envs 2] [--no-cameras] [--repeats 1]
                              [--ppo-repeats 3]
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
from call_warmth import gap_rows  # noqa: E402 - a sibling script: bench/ is on the path of whatever runs this one

import aerobench.envs  # noqa: E402,F401
from aerobench.envs.platforms import CONTROL_HZ, PHYSICS_HZ  # noqa: E402
from aerobench.policies import make_policy  # noqa: E402

SUBSTEPS = PHYSICS_HZ // CONTROL_HZ
SEED = 0


REPEATS = 1  # timings per row; the row reports their minimum (--repeats: other load can only add time)
HOST_PAUSE_US = 40.0  # the pause before the probe call: about two physics steps (17-28 us each), as a step's calls see


def host_line(calls: int = 2000) -> str:
    """How this host prices a call that has not run for a few tens of microseconds (`bench/call_warmth.py`): on
    some hosts such a call costs several times its back-to-back price, whatever ran before it, and every Python-side
    piece of a control step pays that, so the ratios below carry the host's share as well as the code's."""
    hot, after = gap_rows([HOST_PAUSE_US], calls)["torch add"]
    us, cold = after[HOST_PAUSE_US]
    return (f"host: a torch add right after a {HOST_PAUSE_US:g} us pause costs {us / hot:.1f}x its back-to-back price, "
            f"{cold:.0%} of calls cold (bench/call_warmth.py; where calls go cold, the ratios carry the host's share)")


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


def record_episode(env, expert: bool, hover: torch.Tensor, steps: int) -> tuple[list, list, object]:
    """The row's episode run once, untimed (it also compiles and warms the caches): the efforts the controller applied
    at every physics step, the gripper's drive targets at every control step and the final joint positions, for
    `replayed_physics_ms`."""
    base = env.unwrapped
    obs, _ = env.reset(seed=SEED)
    policy = make_policy("expert", base) if expert else None
    if policy is not None:
        policy.reset(torch.arange(1))
    controller = base.agent.body_controller
    articulation = controller._cpu_articulation
    efforts, targets = [], []
    record = controller.before_simulation_step

    def recording():
        record()
        efforts.append(articulation.get_qf().copy())

    controller.before_simulation_step = recording
    try:
        for _ in range(steps):
            obs, _, terminated, truncated, _ = env.step(policy.act(obs) if policy is not None else hover)
            targets.append([joint.get_drive_target().copy() for joint in articulation.active_joints])
            if bool(terminated.any() | truncated.any()):
                break
    finally:
        del controller.before_simulation_step
    return efforts, targets, articulation.get_qpos().copy()


def replayed_physics_ms(env, recorded: tuple[list, list, object]) -> tuple[float, float]:
    """(ms per control step, max joint deviation): the recorded episode (`record_episode`), its 12 PhysX steps per
    control step replayed alone from the same start with the recorded efforts and gripper targets, timing only the
    physics steps (and their `set_qf`). It follows the recorded episode (the deviation of its final joints says how
    closely): the bare step of the same scene in the same states, awake or asleep as they were."""
    efforts, targets, final = recorded
    base = env.unwrapped
    env.reset(seed=SEED)
    articulation, px = base.agent.body_controller._cpu_articulation, base.scene.px  # the reset rebuilt the scene
    spent = 0.0
    for k, step_targets in enumerate(targets):
        for joint, target in zip(articulation.active_joints, step_targets):
            joint.set_drive_target(target)
        t0 = time.perf_counter()
        for qf in efforts[k * SUBSTEPS:(k + 1) * SUBSTEPS]:
            articulation.set_qf(qf)
            px.step()
        spent += time.perf_counter() - t0
    deviation = float(abs(articulation.get_qpos() - final).max())
    return spent / len(targets) * 1e3, deviation


def episode_ms(env, expert: bool, hover: torch.Tensor, max_steps: int) -> float:
    """ms per control step (action and env.step) over the episode from the row's start: with the expert, to the
    episode's end (success, failure or its step limit); hovering, `max_steps` control steps."""
    obs, _ = env.reset(seed=SEED)
    policy = make_policy("expert", env.unwrapped) if expert else None  # as the rollout runner: after the reset
    if policy is not None:
        policy.reset(torch.arange(1))
    spent, steps = 0.0, 0
    for _ in range(max_steps):
        t0 = time.perf_counter()
        obs, _, terminated, truncated, _ = env.step(policy.act(obs) if policy is not None else hover)
        spent += time.perf_counter() - t0
        steps += 1
        if bool(terminated.any() | truncated.any()):
            break
    return spent / steps * 1e3


def aero_rows(env_id: str, steps: int, expert: bool, **kwargs) -> tuple[float, float, float, float]:
    """(ms per control step, ms per bare step of the same scene at rest, ms per replayed bare step of the same
    episode, the replay's deviation). With the expert, one whole episode; hovering, `steps` control steps. After one
    untimed run that records the episode, the episode and its replay are timed in turn `REPEATS` times (so a change
    in the machine's load reaches both), the minimum of each kept."""
    env = gym.make(env_id, num_envs=1, **kwargs)
    env.reset(seed=SEED, options={"reconfigure": True})
    base = env.unwrapped
    hover = torch.zeros(1, base.platform.action_dim)
    hover[:, -1] = -1.0 if env_id == "AeroPlace-v1" else 1.0  # Place starts holding the object: keep it
    max_steps = gym.spec(env_id).max_episode_steps if expert else steps
    cpu = not base.scene.gpu_sim_enabled  # the replay reads and writes the one PhysX articulation of physx_cpu
    if cpu:
        recorded = record_episode(env, expert, hover, max_steps)  # also compiles and warms the caches
    else:
        episode_ms(env, expert, hover, max_steps if expert else 5)  # compiles, warms the caches
    t_ours, replays = float("inf"), []
    for _ in range(REPEATS):
        t_ours = min(t_ours, episode_ms(env, expert, hover, max_steps))
        if cpu:
            replays.append(replayed_physics_ms(env, recorded))
    t_replay, deviation = min(replays) if replays else (float("nan"), float("nan"))  # the fastest replay, its deviation
    t_bare = bare_physics_ms(base, steps)
    env.close()
    return t_ours, t_bare, t_replay, deviation


def maniskill_reference_ms(steps: int) -> tuple[float, float]:
    """(ms per control step, ms per bare step of its scene) of ManiSkill's PickCube-v1, state, a zero action: what
    ManiSkill's own step machinery costs over its physics (its bare step: its physics steps per control step, the
    arm's PD drives holding their targets)."""
    env = gym.make("PickCube-v1", obs_mode="state", num_envs=1)
    env.reset(seed=SEED)
    action = torch.zeros(env.action_space.shape)

    def ours(n):
        for _ in range(n):
            env.step(action)

    t = per_step_ms(ours, steps)
    base = env.unwrapped
    px, substeps = base.scene.px, base._sim_steps_per_control

    def bare(n):
        for _ in range(n * substeps):
            px.step()

    t_bare = per_step_ms(bare, steps)
    env.close()
    return t, t_bare


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
    """Env steps per second of `train_ppo` over its windows after the first (which pays the process start-up): their
    steps over their time (each window logs its own rate and holds the same steps, so the harmonic mean)."""
    import tempfile

    from aerobench.train.common import read_scalars
    from aerobench.train.ppo import PPOConfig, train_ppo

    with tempfile.TemporaryDirectory() as out:
        config = PPOConfig(setting="TidyHouse", skill="pick", objects=("master_chef_can",), out=out, num_envs=num_envs,
                           total_steps=64 * num_envs * windows, hidden=(64, 64), save_every=windows, progress=False)
        train_ppo(config)
        sps = [v for _, v in read_scalars(out, "charts/SPS")][1:]
    return len(sps) / sum(1.0 / v for v in sps)


def ppo_rates(env_counts: list[int], windows: int, repeats: int) -> dict[int, float]:
    """The best env steps per second of `train_ppo` for each K of `env_counts` over `repeats` rounds, the K in turn in
    each round: a change of the host's load between two K's runs then reaches every K alike, as the episode and its
    replay are timed in turn above (one K after the other, a loaded host once gave K = 2 1.50x and once 2.32x)."""
    best = dict.fromkeys(env_counts, 0.0)
    for _ in range(repeats):
        for k in env_counts:
            best[k] = max(best[k], ppo_steps_per_second(k, windows))
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=100, help="control steps timed per row")
    parser.add_argument("--episodes", type=int, default=5, help="expert Pick episodes for the episodes-per-minute row")
    # 8 windows: a window is about 0.2 s, and a reset (about 30 ms) in either worker's window holds the other one
    # up; two timed windows measured which windows held a reset more than the throughput (docs/performance.md)
    parser.add_argument("--ppo-windows", type=int, default=8, help="PPO windows per K (0: skip the PPO rows)")
    parser.add_argument("--ppo-envs", type=lambda t: [int(v) for v in t.split(",")], default=[2],
                        help="K values (> 1) of the worker-process PPO rows, comma-separated")
    parser.add_argument("--no-cameras", action="store_true", help="skip the rendered row (e)")
    parser.add_argument("--repeats", type=int, default=1,
                        help="time each row this many times and report the minimum (on a shared machine)")
    parser.add_argument("--ppo-repeats", type=int, default=3,
                        help="rounds of the PPO rows, the K's in turn, the best rate of each kept "
                             "(docs/performance.md)")
    args = parser.parse_args()
    global REPEATS
    REPEATS = max(1, args.repeats)
    torch.set_num_threads(1)
    print(f"physx_cpu, one env, one torch thread, {SUBSTEPS} physics steps per control step, {args.steps} control "
          f"steps per row")
    print(host_line(), flush=True)
    print(f"{'row':<44} {'ms/step':>9} {'rest ms':>9} {'ratio':>7} {'replay ms':>10} {'ratio':>7} {'replay dev':>11}")
    reference, reference_bare = maniskill_reference_ms(args.steps)
    print(f"{'(b) ManiSkill PickCube-v1, state':<44} {reference:9.2f} {reference_bare:9.3f} "
          f"{reference / reference_bare:6.1f}x", flush=True)
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
        ours, bare, replay, deviation = aero_rows(env_id, steps, expert, **kwargs)
        # two decimals: a goal such as Fly <= 1.5x is judged on the ratio, not on its rounding
        print(f"{label:<44} {ours:9.3f} {bare:9.3f} {ours / bare:6.2f}x {replay:10.3f} {ours / replay:6.2f}x "
              f"{deviation:11.1e}", flush=True)
    print("(a) the bare PhysX step of each row's scene: 'rest ms', the scene after the row, its 12 PhysX steps with "
          "the efforts frozen; 'replay ms', the row's own episode replayed in PhysX alone (its recorded efforts and "
          "gripper targets; 'replay dev': its final joints' largest deviation from the episode, m or rad). Goals: "
          "Pick with the expert <= 3x, Fly <= 1.5x")
    print(f"AeroPick-v1 reset with a new layout: {reset_ms():.0f} ms (median of 15)")
    rate, successes, steps = expert_episodes_per_min(args.episodes)
    print(f"expert Pick episodes per minute on one core: {rate:.1f} ({successes}/{args.episodes} successful, "
          f"{steps} control steps)")
    if args.ppo_windows >= 2:
        rounds = max(1, args.ppo_repeats)
        rates = ppo_rates([1, *args.ppo_envs], args.ppo_windows, rounds)
        how = f", the best of {rounds} runs in turn" if rounds > 1 else ""
        one = rates[1]
        print(f"train ppo env steps per second{how}: K=1 {one:.1f}")
        for k in args.ppo_envs:
            sps = rates[k]
            print(f"train ppo env steps per second{how}: K={k} worker processes {sps:.1f} ({sps / one:.2f}x of K=1"
                  + ("; goal >= 1.8x on 2 cores)" if k == 2 else ")"), flush=True)


if __name__ == "__main__":
    main()
