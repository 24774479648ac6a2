"""Pictures of an env: the three onboard RGB-D views beside a third-person view (`aerobench render`)."""

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


def _label(img: np.ndarray, text: str) -> np.ndarray:
    import cv2

    img = np.ascontiguousarray(img)
    (w, h), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, 0.45, 1)
    img[: h + 10, : min(w + 10, img.shape[1])] //= 3  # a dark strip behind the label
    cv2.putText(img, text, (5, h + 5), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 255), 1, cv2.LINE_AA)
    return img


def compose_views(sensor_data: dict, third_person: np.ndarray, title: str = "") -> np.ndarray:
    """One picture: third-person view on the left, RGB (top) and depth (bottom) of the three cameras on the right."""
    import cv2

    rgb = [cv2.resize(sensor_data[c]["rgb"], (TILE, TILE), interpolation=cv2.INTER_NEAREST) for c in CAMERAS]
    depth = [cv2.resize(depth_to_color(sensor_data[c]["depth"]), (TILE, TILE), interpolation=cv2.INTER_NEAREST) for c in CAMERAS]
    rgb = [_label(img, c) for img, c in zip(rgb, CAMERAS)]
    depth = [_label(img, f"{c} depth") for img, c in zip(depth, CAMERAS)]
    right = np.concatenate([np.concatenate(rgb, 1), np.concatenate(depth, 1)], 0)
    left = cv2.resize(third_person, (right.shape[0], right.shape[0]))
    left = _label(left, title) if title else left
    return np.concatenate([left, right], 1)


def _compose_from_obs(env, obs) -> np.ndarray:
    sensors = {c: {k: v[0].cpu().numpy() for k, v in obs["sensor_data"][c].items()} for c in CAMERAS}
    third = env.render()[0].cpu().numpy().astype(np.uint8)
    return compose_views(sensors, third, env.unwrapped.get_instruction(0))


def render_env(env_id: str, seed: int = 0, **kwargs) -> np.ndarray:
    """Reset `env_id` with `seed` and return the composed picture `(H, W, 3)` uint8."""
    import aerobench.envs  # noqa: F401

    env = gym.make(env_id, obs_mode="rgbd", render_mode="rgb_array", **kwargs)
    try:
        obs, _ = env.reset(seed=seed)
        return _compose_from_obs(env, obs)
    finally:
        env.close()


def rollout_frames(env_id: str, steps: int, seed: int = 0, policy: str = "random", every: int = 1, **kwargs) -> list[np.ndarray]:
    """Composed pictures of one episode of `policy` (a registered policy name), every `every` control steps."""
    import torch

    import aerobench.envs  # noqa: F401
    from aerobench.policies import make_policy

    env = gym.make(env_id, obs_mode="rgbd", render_mode="rgb_array", **kwargs)
    try:
        obs, _ = env.reset(seed=seed)
        actor = make_policy(policy, env.unwrapped, seed=seed) if policy == "random" else make_policy(policy, env.unwrapped)
        actor.reset(torch.arange(1))
        frames = [_compose_from_obs(env, obs)]
        for k in range(steps):
            obs, _, terminated, truncated, _ = env.step(actor.act(obs))
            if k % every == 0:
                frames.append(_compose_from_obs(env, obs))
            if bool(terminated[0]) or bool(truncated[0]):
                break
        return frames
    finally:
        env.close()
