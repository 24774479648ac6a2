"""Every camera frame of an aerobench dataset, decoded once and reduced to a network's input size.

LeRobot's `dataset[i]` decodes the frame's three videos around i (a seek each) and the packed depth PNGs: about
0.7 s per frame on this project's CPU, so hours for a camera dataset. A trainer wants every frame of the chosen
episodes once, in order. This reads each video file front to back (one PyAV decode per file), takes the depth
images from the parquet in bulk, and keeps per camera a uint8 `(T, 4, s, s)` tensor: RGB, and depth in 2 cm
levels, reduced exactly as a policy reduces its cameras when it acts (`policies.camera_input`). It is cached under the dataset's `.aerobench/cache/`, keyed by the image size and the
dataset's files, so training runs of the same data (seeds, blind controls, learning curves) decode it once.

Frame k of an episode is frame `round(from_timestamp * fps) + k` of its video file (LeRobot v3 concatenates the
episodes of a file at their recorded timestamps; tests/train/test_camera_frames.py checks it against
`LeRobotDataset[i]`).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import torch

from ..depth import decode_depth_mm
from ..export.features import depth_key, rgb_key
from ..file_lock import exclusive
from ..policies.camera_input import IMAGE_CHANNELS, reduce_depth, reduce_rgb

CACHE_DIR = ".aerobench/cache"
CACHE_FORMAT = 1


def _fingerprint(root: Path, cameras: tuple[str, ...], size: int) -> str:
    """Changes with the dataset's files (an edited or re-merged dataset decodes again)."""
    files = sorted(p for d in ("data", "videos", "meta") for p in (root / d).rglob("*") if p.is_file())
    stamp = [(str(p.relative_to(root)), p.stat().st_size, p.stat().st_mtime_ns) for p in files]
    key = json.dumps([CACHE_FORMAT, list(cameras), size, stamp])
    return hashlib.sha256(key.encode()).hexdigest()[:16]


DECODE_CHUNK = 512  # frames decoded at full size before they are reduced (a file may hold 100k frames)


def _decode_video(path: Path, size: int) -> torch.Tensor:
    """Every frame of an mp4, in order, reduced: uint8 `(N, 3, size, size)`."""
    import av

    reduced, chunk = [], []
    with av.open(str(path)) as container:
        for frame in container.decode(video=0):
            chunk.append(frame.to_ndarray(format="rgb24"))
            if len(chunk) == DECODE_CHUNK:
                reduced.append(reduce_rgb(torch.from_numpy(np.stack(chunk)).permute(0, 3, 1, 2), size))
                chunk = []
    if chunk:
        reduced.append(reduce_rgb(torch.from_numpy(np.stack(chunk)).permute(0, 3, 1, 2), size))
    return torch.cat(reduced)


def _episode_table(root: Path) -> list[dict]:
    """meta/episodes rows (one per episode, in episode order)."""
    import pandas as pd

    files = sorted((root / "meta" / "episodes").rglob("*.parquet"))
    table = pd.concat([pd.read_parquet(f) for f in files]).sort_values("episode_index")
    return table.to_dict("records")


def decode_all(root: Path, cameras: tuple[str, ...], size: int) -> dict[str, torch.Tensor]:
    """Per camera, uint8 `(total_frames, 4, size, size)` for every frame of the dataset, in dataset order."""
    import pyarrow.parquet as pq

    info = json.loads((root / "meta" / "info.json").read_text())
    fps, total = info["fps"], info["total_frames"]
    episodes = _episode_table(root)
    out = {cam: torch.zeros(total, IMAGE_CHANNELS, size, size, dtype=torch.uint8) for cam in cameras}
    for cam in cameras:
        key = rgb_key(cam)
        by_file: dict[tuple[int, int], list[dict]] = {}
        for ep in episodes:
            by_file.setdefault((int(ep[f"videos/{key}/chunk_index"]), int(ep[f"videos/{key}/file_index"])), []).append(ep)
        for (chunk, file), eps in by_file.items():
            path = root / info["video_path"].format(video_key=key, chunk_index=chunk, file_index=file)
            frames = _decode_video(path, size)
            for ep in eps:
                first = int(round(float(ep[f"videos/{key}/from_timestamp"]) * fps))
                n = int(ep["length"])
                if first + n > len(frames):
                    raise ValueError(f"{path} has {len(frames)} frames; episode {ep['episode_index']} needs "
                                     f"{first}-{first + n}: the dataset's videos are incomplete (re-merge it)")
                rows = slice(int(ep["dataset_from_index"]), int(ep["dataset_to_index"]))
                out[cam][rows, :3] = frames[first:first + n]
    start = 0
    for f in sorted((root / "data").rglob("*.parquet")):  # data files hold the frames in dataset order
        batches = pq.ParquetFile(f).iter_batches(batch_size=DECODE_CHUNK, columns=["index", *map(depth_key, cameras)])
        for batch in batches:
            index = torch.tensor(batch.column("index").to_numpy())
            for cam in cameras:
                packed = np.stack([_png(im["bytes"]) for im in batch.column(depth_key(cam)).to_pylist()])
                depth = torch.from_numpy(decode_depth_mm(packed).astype(np.int32))
                out[cam][index, 3:] = reduce_depth(depth, size)
            start += len(index)
    if start != total:
        raise ValueError(f"{root}'s data files hold {start} frames; meta/info.json says {total}")
    return out


def _png(data: bytes) -> np.ndarray:
    import io

    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))


def camera_frames(root: str | Path, cameras: tuple[str, ...], size: int) -> dict[str, torch.Tensor]:
    """Per camera, uint8 `(total_frames, 4, size, size)` (RGB, depth levels), decoded once per
    dataset, camera set and size and then read from the dataset's cache."""
    root = Path(root)
    if not cameras:
        return {}
    missing = [c for c in cameras if not (root / "videos" / rgb_key(c)).is_dir()]
    if missing:
        raise ValueError(f"{root} has no videos of {', '.join(missing)}: export it with cameras (aerobench generate "
                         f"without --no-cameras)")
    cache = root / CACHE_DIR / f"frames-{size}-{'-'.join(cameras)}-{_fingerprint(root, cameras, size)}.pt"
    if cache.is_file():
        return torch.load(cache)
    cache.parent.mkdir(parents=True, exist_ok=True)
    with exclusive(cache.parent / "decode.lock"):  # two trainers on one dataset decode it once
        if cache.is_file():
            return torch.load(cache)
        frames = decode_all(root, cameras, size)
        for old in cache.parent.glob(f"frames-{size}-{'-'.join(cameras)}-*.pt"):
            old.unlink()  # the dataset changed since: its old frames are of no use
        tmp = cache.with_suffix(".tmp")
        torch.save(frames, tmp)
        tmp.rename(cache)
    return frames
