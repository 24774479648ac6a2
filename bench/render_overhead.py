"""Per-control-step cost of a skill env with the three 128x128 RGB-D cameras against bare rendering.

ours: `env.step` of AeroPick-v1 with obs_mode="rgbd" (physics + flight controller + signals + three cameras).
bare: the same scene's three cameras rendered by SAPIEN/ManiSkill alone (update_render, capture, read back), with
no physics step and no aerobench code. Prints milliseconds per control step and the ratio.

    python bench/render_overhead.py [--steps 30]
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


def measure(setting: str, steps: int, sim_backend: str = "physx_cpu", num_envs: int = 1) -> tuple[float, float, float]:
    env = gym.make("AeroPick-v1", obs_mode="rgbd", setting=setting, sim_backend=sim_backend, num_envs=num_envs)
    env.reset(seed=0)
    base = env.unwrapped
    action = torch.zeros(num_envs, base.platform.action_dim, device=base.device)
    action[:, -1] = 1.0

    def ours(n):
        for _ in range(n):
            env.step(action)

    def bare(n):
        for _ in range(n):
            base.scene.update_render(update_sensors=True, update_human_render_cameras=False)
            base.capture_sensor_data()
            base.get_sensor_images()

    def state_only(n):
        for _ in range(n):
            base._step_action(action)
            base.evaluate()

    timings = []
    for fn in (ours, bare, state_only):
        fn(3)
        t0 = time.perf_counter()
        fn(steps)
        timings.append((time.perf_counter() - t0) / steps * 1e3)
    env.close()
    return tuple(timings)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=30)
    args = parser.parse_args()
    print(f"AeroPick-v1, obs_mode=rgbd (3 x 128x128 RGB-D), one env, {args.steps} control steps per row")
    print(f"{'setting':<18} {'ours ms':>9} {'bare render ms':>15} {'ratio':>7} {'no-render step ms':>18}")
    for setting in ("TidyHouse", "PrepareGroceries", "PackageDelivery"):
        ours, bare, state = measure(setting, args.steps)
        print(f"{setting:<18} {ours:9.1f} {bare:15.1f} {ours / bare:7.2f}x {state:18.1f}")
    if torch.cuda.is_available():
        print("\nphysx_cuda, TidyHouse:")
        for n in (1, 16, 64, 256):
            ours, bare, state = measure("TidyHouse", 10, "physx_cuda", n)
            print(f"N={n:<5d} ours {ours:8.1f} ms  bare {bare:8.1f} ms  ratio {ours / bare:5.2f}x  {n / ours * 1e3:8.0f} env-steps/s")
    else:
        print("\nphysx_cuda timings skipped: no CUDA GPU on this machine (see docs/gpu.md)")


if __name__ == "__main__":
    main()
