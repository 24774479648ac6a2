"""Lossless depth codec: 16-bit millimetre depth packed into an RGB uint8 image.

LeRobot stores an "image" feature as PNG bytes inside the data parquet, which is lossless but 8 bits per channel,
and its own depth-video path quantizes to 12 bits. aerobench keeps depth exact instead:

    mm = depth in millimetres, uint16 (0 = no return / beyond the camera's range)
    R = mm >> 8,  G = mm & 255,  B = min(mm / 20, 255)

so `mm = 256 * R + G`. B is a coarse linear copy (20 mm a level, 0-5.1 m) for networks that read the packed image
as a picture, as LeRobot's ACT and Diffusion Policy do with any 3-channel image feature: R is depth in 256 mm steps
and G a sawtooth, neither a smooth depth image. Datasets written before B was added hold B = 0 (`DEPTH_ENCODING`
names the form in meta/aerobench.json); the exact decode reads R and G only, so both forms decode alike.
LeRobot hands a decoded image back as float32 CHW in [0, 1] (= uint8 / 255); `decode_depth_mm` accepts that form
and the raw uint8 HWC form alike.
"""

from __future__ import annotations

import numpy as np
import torch

DEPTH_CHANNELS = 3  # R = high byte, G = low byte, B = linear copy (three channels so the PNG is a plain RGB image)
HIGH_BYTE_SHIFT = 8
LOW_BYTE_MASK = 0xFF
UINT8_MAX = 255
LINEAR_STEP_MM = 20  # B's step: 255 levels cover 0-5.1 m, the indoor scenes' depths (farther reads 255)
DEPTH_ENCODING = ("uint16 millimetres packed as R = mm >> 8, G = mm & 255, B = min(mm // 20, 255) (a coarse linear "
                  "copy for CNNs; 0 = no return)")


def encode_depth_mm(depth_mm: np.ndarray) -> np.ndarray:
    """`(H, W)` or `(H, W, 1)` uint16 millimetres -> `(H, W, 3)` uint8 image (R high byte, G low byte, B linear)."""
    depth = np.asarray(depth_mm)
    if depth.ndim == 3 and depth.shape[-1] == 1:
        depth = depth[..., 0]
    if depth.ndim != 2:
        raise ValueError(f"depth must be (H, W) or (H, W, 1), got shape {depth.shape}")
    if depth.dtype != np.uint16:
        raise ValueError(f"depth must be uint16 millimetres, got dtype {depth.dtype}")
    packed = np.zeros((*depth.shape, DEPTH_CHANNELS), dtype=np.uint8)
    packed[..., 0] = depth >> HIGH_BYTE_SHIFT
    packed[..., 1] = depth & LOW_BYTE_MASK
    packed[..., 2] = np.minimum(depth // LINEAR_STEP_MM, UINT8_MAX)
    return packed


def pack_depth(depth_mm: torch.Tensor) -> torch.Tensor:
    """`encode_depth_mm` for a batch on its own device: `(N, H, W)` millimetres (any integer or float dtype, clipped
    to 0-65535) -> uint8 `(N, H, W, 3)`; no copy to the host (a policy adapter's per-step path on physx_cuda)."""
    depth = depth_mm.to(torch.int32).clamp(0, 65535)
    packed = torch.stack([depth >> HIGH_BYTE_SHIFT, depth & LOW_BYTE_MASK,
                          torch.clamp(depth // LINEAR_STEP_MM, max=UINT8_MAX)], dim=-1)
    return packed.to(torch.uint8)


def _as_uint8_hwc(image: np.ndarray | torch.Tensor) -> np.ndarray:
    """Either uint8 `(..., H, W, 3)` or LeRobot's float `(..., 3, H, W)` in [0, 1] -> uint8 `(..., H, W, 3)`."""
    if isinstance(image, torch.Tensor):
        image = image.detach().cpu().numpy()
    image = np.asarray(image)
    if image.dtype == np.uint8:
        if image.shape[-1] != DEPTH_CHANNELS:
            raise ValueError(f"uint8 packed depth must be (..., H, W, 3), got shape {image.shape}")
        return image
    if not np.issubdtype(image.dtype, np.floating):
        raise ValueError(f"packed depth must be uint8 HWC or float CHW in [0, 1], got dtype {image.dtype}")
    if image.ndim < 3 or image.shape[-3] != DEPTH_CHANNELS:
        raise ValueError(f"float packed depth must be (..., 3, H, W), got shape {image.shape}")
    # Rounding undoes LeRobot's uint8 / 255 exactly (the float error is far below half a step).
    return np.moveaxis(np.rint(image * UINT8_MAX), -3, -1).astype(np.uint8)


def decode_depth_mm(image: np.ndarray | torch.Tensor) -> np.ndarray:
    """Packed depth (uint8 HWC, or LeRobot's float CHW in [0, 1], optionally batched) -> uint16 mm `(..., H, W)`."""
    packed = _as_uint8_hwc(image)
    high = packed[..., 0].astype(np.uint16)
    low = packed[..., 1].astype(np.uint16)
    return (high << HIGH_BYTE_SHIFT) | low
