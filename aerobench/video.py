"""Writing an MP4 from frames: the one video writer of the flight runner, the demo and evaluation (floor 1)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

# libx264's yuv420p needs even sides; every frame aerobench writes has them (128, 384 and their sums), so nothing is
# rescaled (a block of 16, imageio's default, rescaled some frames with a warning)
MACRO_BLOCK = 2


def write_video(frames: list[np.ndarray], path: Path, fps: int) -> None:
    """H.264 MP4 through imageio's bundled ffmpeg (no system FFmpeg needed)."""
    import imageio.v2 as imageio

    path.parent.mkdir(parents=True, exist_ok=True)
    imageio.mimwrite(path, [np.asarray(f, dtype=np.uint8) for f in frames], fps=fps, macro_block_size=MACRO_BLOCK)
