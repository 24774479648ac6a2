"""Per-control-step cost of the aerobench airframe against bare SAPIEN physics with the same bodies.

ours: the flight controller at every physics step (state read, controller, Q = J^T W, write) + 12 physics steps.
bare: the same scene stepped 12 times, holding the hover joint efforts constant (no controller).
Prints milliseconds per control step and the ratio (goal: at most 1.3x), then the pure controller's cost per env
as the batch grows (how the torch controller amortizes on batched envs), and physx_cuda timings where a GPU exists.

    python bench/flight_overhead.py [--steps 200]
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
from aerobench.envs.control.flight import FlightMemory, FlightParams, flight_step  # noqa: E402
from aerobench.envs.control.virtual_joints import AirframeState  # noqa: E402
from aerobench.envs.platforms import CONTROL_HZ, PHYSICS_HZ, get_platform  # noqa: E402

SUBSTEPS = PHYSICS_HZ // CONTROL_HZ


def time_per_control_step(fn, steps: int) -> float:
    fn(10)  # warm-up
    t0 = time.perf_counter()
    fn(steps)
    return (time.perf_counter() - t0) / steps * 1e3


def sim_overhead(platform: str, scene: str, steps: int, sim_backend: str = "physx_cpu", num_envs: int = 1) -> tuple[float, float]:
    env = gym.make("AeroFly-v1", obs_mode="none", scene=scene, platform=platform, sim_backend=sim_backend, num_envs=num_envs)
    env.reset(seed=0)
    base = env.unwrapped
    agent, px = base.agent, base.scene.px
    action = torch.zeros(num_envs, get_platform(platform).action_dim, device=base.device)
    agent.set_action(action)
    gpu = base.gpu_sim_enabled

    def step_physics():
        px.step()
        if gpu:
            base.scene._gpu_fetch_all()

    def ours(n):
        for _ in range(n):
            agent.set_action(action)
            for _ in range(SUBSTEPS):
                agent.before_simulation_step()
                step_physics()

    agent.before_simulation_step()  # writes the hover efforts once; bare physics then reuses them
    hover_qf = agent.robot.get_qf().clone()

    def bare(n):
        for _ in range(n):
            for _ in range(SUBSTEPS):
                agent.robot.set_qf(hover_qf)
                if gpu:
                    px.gpu_apply_articulation_qf()
                step_physics()

    env.reset(seed=0)
    t_ours = time_per_control_step(ours, steps)
    env.reset(seed=0)
    t_bare = time_per_control_step(bare, steps)
    env.close()
    return t_ours, t_bare


def controller_cost_per_env(num_envs: int, device: str, steps: int = 50) -> float:
    """Microseconds per env per physics step of the pure controller (no simulator)."""
    params = FlightParams.from_platform(get_platform("gripper"), device)
    memory = FlightMemory.initial(num_envs, params, device)
    state = AirframeState(
        torch.zeros(num_envs, 3, device=device),
        torch.zeros(num_envs, 3, device=device),
        torch.eye(3, device=device).expand(num_envs, 3, 3).contiguous(),
        torch.zeros(num_envs, 3, device=device),
    )
    v_cmd, yaw_rate = torch.full((num_envs, 3), 0.3, device=device), torch.zeros(num_envs, device=device)
    for _ in range(5):
        flight_step(state, v_cmd, yaw_rate, memory, params)
    if device == "cuda":
        torch.cuda.synchronize()
    t0 = time.perf_counter()
    for _ in range(steps):
        flight_step(state, v_cmd, yaw_rate, memory, params)
    if device == "cuda":
        torch.cuda.synchronize()
    return (time.perf_counter() - t0) / steps / num_envs * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=200, help="control steps timed per measurement")
    args = parser.parse_args()
    print(f"physx_cpu, one env, {SUBSTEPS} physics steps per control step, {args.steps} control steps per row")
    print(f"{'platform':<8} {'scene':<6} {'ours ms':>9} {'bare ms':>9} {'ratio':>7}  goal <= 1.3x")
    for platform in ("gripper", "arm"):
        for scene in ("empty", "room"):
            ours, bare = sim_overhead(platform, scene, args.steps)
            print(f"{platform:<8} {scene:<6} {ours:9.3f} {bare:9.3f} {ours / bare:7.1f}x")
    print("\npure flight controller (flight_step), microseconds per env per physics step, CPU torch:")
    for n in (1, 16, 256, 4096):
        print(f"  N={n:<5d} {controller_cost_per_env(n, 'cpu'):10.2f}")
    if torch.cuda.is_available():
        print("\nphysx_cuda, gripper platform, empty scene:")
        print(f"{'N':>6} {'ours ms':>9} {'bare ms':>9} {'ratio':>7} {'env-steps/s':>12}")
        for n in (1, 16, 256, 1024, 4096):
            ours, bare = sim_overhead("gripper", "empty", 50, "physx_cuda", n)
            print(f"{n:6d} {ours:9.3f} {bare:9.3f} {ours / bare:7.2f}x {n / ours * 1e3:12.0f}")
    else:
        print("\nphysx_cuda timings skipped: no CUDA GPU on this machine (see docs/gpu.md)")


if __name__ == "__main__":
    main()
