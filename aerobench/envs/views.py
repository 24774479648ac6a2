"""Pictures of an env: the three onboard RGB-D views beside a third-person view (`aerobench render`), the instruction
above them (wrapped, never cut) and one depth colour scale for every depth panel (fixed: the same colour is the same
distance in every picture)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

CAMERAS = ("drone_front", "drone_hand", "drone_own")
TILE = 192  # onboard 128x128 views are shown at 1.5x
DEPTH_RANGE_MM = (0, 4000)


def depth_to_color(depth_mm: np.ndarray) -> np.ndarray:
    """int16 millimetres `(H, W, 1)` -> a turbo colour image `(H, W, 3)` uint8 (near = blue, far = red, 0 = black)."""
    import cv2

    d = depth_mm[..., 0].astype(np.float32)
    lo, hi = DEPTH_RANGE_MM
    scaled = np.clip((d - lo) / (hi - lo) * 255.0, 0, 255).astype(np.uint8)
    color = cv2.applyColorMap(scaled, cv2.COLORMAP_TURBO)[..., ::-1]
    color[d <= 0] = 0
    return color


def _wrapped(text: str, width_px: int, scale: float = 0.45) -> list[str]:
    """`text` broken into lines that fit `width_px` pixels at the label font."""
    import cv2

    lines, line = [], ""
    for word in text.split():
        candidate = f"{line} {word}".strip()
        if line and cv2.getTextSize(candidate, cv2.FONT_HERSHEY_SIMPLEX, scale, 1)[0][0] > width_px:
            lines.append(line)
            line = word
        else:
            line = candidate
    return [*lines, line] if line else lines


def _title_strip(text: str, width: int) -> np.ndarray:
    """A dark strip `width` wide holding `text`, wrapped over as many lines as it needs."""
    import cv2

    lines = _wrapped(text, width - 10)
    strip = np.full((8 + 18 * len(lines), width, 3), 30, dtype=np.uint8)
    for i, line in enumerate(lines):
        cv2.putText(strip, line, (5, 18 + 18 * i), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 255), 1, cv2.LINE_AA)
    return strip


def _depth_scale(width: int) -> np.ndarray:
    """The depth panels' colour scale: a bar `width` wide from 0 to `DEPTH_RANGE_MM`'s end, labelled in metres."""
    import cv2

    lo, hi = DEPTH_RANGE_MM
    ramp = np.linspace(lo, hi, width, dtype=np.float32)[None, :, None].repeat(14, 0)
    bar = np.full((34, width, 3), 30, dtype=np.uint8)
    bar[2:16] = depth_to_color(ramp.astype(np.int32))
    for k in range(0, int(hi / 1000) + 1):
        x = min(int(k * 1000 / (hi - lo) * (width - 1)), width - 30)
        cv2.putText(bar, f"{k} m", (x + 2, 30), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 255), 1, cv2.LINE_AA)
    return bar


def _label(img: np.ndarray, text: str) -> np.ndarray:
    import cv2

    img = np.ascontiguousarray(img)
    (w, h), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, 0.45, 1)
    img[: h + 10, : min(w + 10, img.shape[1])] //= 3  # a dark strip behind the label
    cv2.putText(img, text, (5, h + 5), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 255), 1, cv2.LINE_AA)
    return img


def compose_views(sensor_data: dict, third_person: np.ndarray, title: str = "") -> np.ndarray:
    """One picture: the instruction on top; the third-person view on the left, RGB (top) and depth (bottom) of the three
    cameras on the right, and the depth colour scale under them."""
    import cv2

    rgb = [cv2.resize(sensor_data[c]["rgb"], (TILE, TILE), interpolation=cv2.INTER_NEAREST) for c in CAMERAS]
    depth = [cv2.resize(depth_to_color(sensor_data[c]["depth"]), (TILE, TILE), interpolation=cv2.INTER_NEAREST) for c in CAMERAS]
    rgb = [_label(img, c) for img, c in zip(rgb, CAMERAS)]
    depth = [_label(img, f"{c} depth") for img, c in zip(depth, CAMERAS)]
    right = np.concatenate([np.concatenate(rgb, 1), np.concatenate(depth, 1)], 0)
    right = np.concatenate([right, _depth_scale(right.shape[1])], 0)
    left = cv2.resize(third_person, (right.shape[0], right.shape[0]))
    picture = np.concatenate([left, right], 1)
    if title:
        picture = np.concatenate([_title_strip(title, picture.shape[1]), picture], 0)
    return picture[: picture.shape[0] // 2 * 2, : picture.shape[1] // 2 * 2]  # even sides: H.264 frames


def compose_from_obs(env, obs) -> np.ndarray:
    sensors = {c: {k: v[0].cpu().numpy() for k, v in obs["sensor_data"][c].items()} for c in CAMERAS}
    third = env.render()[0].cpu().numpy().astype(np.uint8)
    return compose_views(sensors, third, env.unwrapped.get_instruction(0))


def render_env(env_id: str, seed: int = 0, **kwargs) -> np.ndarray:
    """Reset `env_id` with `seed` and return the composed picture `(H, W, 3)` uint8."""
    import aerobench.envs  # noqa: F401

    env = gym.make(env_id, obs_mode="rgbd", render_mode="rgb_array", **kwargs)
    try:
        obs, _ = env.reset(seed=seed)
        return compose_from_obs(env, obs)
    finally:
        env.close()
