"""Ray-traced against rasterized cameras (spec appendix "Ray Tracing"): milliseconds per rendered control step of
AeroPick-v1 with the three RGB-D cameras, their ratio, and a side-by-side picture of the third-person view.

    python bench/ray_tracing.py [--steps 5] [--picture docs/img/ray_tracing.png]

Ray tracing needs a GPU with Vulkan ray tracing; on a machine without one the script prints the env's one-line
reason and measures only the rasterized row (exit status 0, so `make bench` goes on).
"""

from __future__ import annotations

import argparse
import logging
import os
import time

os.environ.setdefault("MS_SKIP_ASSET_DOWNLOAD_PROMPT", "1")
logging.getLogger("mani_skill").setLevel(logging.ERROR)

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402

import aerobench.envs  # noqa: E402,F401
from aerobench.envs.rendering import ray_tracing_device, require_ray_tracing  # noqa: E402
from aerobench.envs.views import render_env  # noqa: E402


def ms_per_step(rendering: str, setting: str, steps: int, seed: int) -> float:
    env = gym.make("AeroPick-v1", obs_mode="rgbd", setting=setting, rendering=rendering)
    try:
        env.reset(seed=seed)
        base = env.unwrapped
        action = torch.zeros(1, base.platform.action_dim)
        action[:, -1] = 1.0
        env.step(action)  # first render builds the pipelines
        start = time.perf_counter()
        for _ in range(steps):
            env.step(action)
        return (time.perf_counter() - start) * 1000.0 / steps
    finally:
        env.close()


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--setting", default="TidyHouse")
    p.add_argument("--steps", type=int, default=5)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--picture", default=None, help="write rasterized | ray-traced third-person views side by side")
    args = p.parse_args()
    device = ray_tracing_device()
    raster = ms_per_step("rasterized", args.setting, args.steps, args.seed)
    print(f"rasterized   {raster:9.1f} ms per control step (AeroPick-v1 {args.setting}, 3 RGB-D cameras)")
    if device is None:
        try:
            require_ray_tracing()
        except ValueError as e:
            print(f"ray-traced   not measured: {e}")
        return 0
    traced = ms_per_step("ray-traced", args.setting, args.steps, args.seed)
    print(f"ray-traced   {traced:9.1f} ms per control step on {device.name}")
    print(f"ratio ray-traced / rasterized: {traced / raster:.1f}x")
    if args.picture:
        import imageio.v2 as imageio

        views = [render_env("AeroPick-v1", seed=args.seed, setting=args.setting, rendering=r)
                 for r in ("rasterized", "ray-traced")]
        imageio.imwrite(args.picture, np.concatenate(views, axis=1))
        print(f"wrote {args.picture}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
