"""An env's conditions while it runs: their own per-env random streams, each episode's draws, and the state they keep.

Randomness: env i owns one torch CPU generator per model that draws (wind, sensor, camera), seeded from its episode
seed and the model's stream id (`condition_seed`), never from the reset's generators (`episode_rng`), so every
condition starts from the same starts as the nominal run, and a model draws the same whatever other conditions run
beside it.
All of an episode's draws are made when it starts (`start_episodes`, for the envs being reset, one call per env as
`episode_rng` does), so a batch of N envs draws exactly what N single envs draw, and the step never draws: the wind's
heading and initial turbulence, then `WIND_NOISE_HORIZON_STEPS` control steps of white noise per model (an episode
longer than that repeats its noise). The camera noise draws one key per episode; each frame's noise is a hash of it
(`visual.hashed_normals`). The surface colours draw once per build from their own stream (`stream_generator`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
import torch

from ..control.virtual_joints import AirframeState
from ..platforms import CONTROL_HZ, PlatformSpec
from .constants import WIND_NOISE_HORIZON_STEPS
from .physics import ConditionedPhysics
from .registry import ConditionSet
from .sensors import NOISE_WIDTH, STATE_WIDTH, DelayLine, add_noise, airframe_state, flat_state
from .visual import camera_counter, hashed_normals, motion_blur, noisy_depth, noisy_rgb, rotational_flow
from .wind import gauss_markov_step, onset, wind_world

WIND_STREAM, SENSOR_STREAM, CAMERA_STREAM, SURFACE_STREAM = 1, 2, 3, 4  # the models' stream ids, mixed with the seed
CAMERA_KEY_RANGE = 2**32  # an episode's camera noise key: a 32-bit hash input


def condition_seed(episode_seed: int, stream: int) -> int:
    """A 63-bit seed for a model's stream of one episode (numpy's SeedSequence mixes the two: neighbouring episode
    seeds give unrelated streams, and none equals the reset's own `torch.manual_seed(episode_seed)` stream)."""
    return int(np.random.SeedSequence([int(episode_seed), stream]).generate_state(1, np.uint64)[0] >> np.uint64(1))


def stream_generator(episode_seed: int, stream: int) -> torch.Generator:
    """A CPU generator of a model's stream of one episode (for draws made outside the runtime: the build's)."""
    return torch.Generator().manual_seed(condition_seed(episode_seed, stream))


class ConditionRuntime:
    """The conditions of one env of `num_envs` parallel envs. `surfaces()`: the env's packed static boxes (or None)."""

    def __init__(self, condition: ConditionSet, platform: PlatformSpec, num_envs: int, device: torch.device | str,
                 surfaces: Callable[[], torch.Tensor | None], horizon: int = WIND_NOISE_HORIZON_STEPS):
        self.condition, self.num_envs, self.device, self.horizon = condition, num_envs, torch.device(device), horizon
        self.physics = (ConditionedPhysics(condition, platform, num_envs, device, surfaces)
                        if condition.is_physical else None)
        self.generators: dict[int, list[torch.Generator]] = {}
        wind = condition.wind
        if wind is not None:
            self.generators[WIND_STREAM] = [torch.Generator() for _ in range(num_envs)]
            sigma, _ = wind.turbulence()
            self.wind_sigma = torch.tensor(sigma, device=device)
            self.wind_a = torch.tensor(wind.correlation(1.0 / CONTROL_HZ), device=device)
            self.wind_heading = torch.zeros(num_envs, device=device)
            self.turbulence = torch.zeros(num_envs, 3, device=device)
            self.wind_noise = torch.zeros(num_envs, horizon, 3, device=device)
            self.onset_steps = wind.onset_s * CONTROL_HZ
        if condition.sensor_noise is not None:
            self.generators[SENSOR_STREAM] = [torch.Generator() for _ in range(num_envs)]
            self.sensor_noise = torch.zeros(num_envs, horizon, NOISE_WIDTH, device=device)
        if condition.camera_noise is not None:
            self.generators[CAMERA_STREAM] = [torch.Generator() for _ in range(num_envs)]
            self.camera_keys = torch.zeros(num_envs, dtype=torch.long, device=device)
        delay = condition.sensor_delay
        self.delay = DelayLine(num_envs, STATE_WIDTH, delay.steps if delay is not None else 0, device)
        self._envs = torch.arange(num_envs, device=device)

    # ----------------------------------------------------------------------------------------------------------------
    # Episodes
    # ----------------------------------------------------------------------------------------------------------------
    def seed(self, rows: Sequence[int], seeds: Sequence[int]) -> None:
        """Restart the streams of envs `rows` at their new episode seeds."""
        for stream, generators in self.generators.items():
            for i, s in zip(rows, seeds):
                generators[i].manual_seed(condition_seed(int(s), stream))

    def start_episodes(self, rows: Sequence[int]) -> None:
        """Draw the new episodes' sequences for envs `rows` and reset what the models keep for them."""
        rows = [int(i) for i in rows]
        if not rows:
            return
        index = torch.tensor(rows, device=self.device)
        if WIND_STREAM in self.generators:
            draws = [self._wind_draws(self.generators[WIND_STREAM][i]) for i in rows]
            self.wind_heading[index] = torch.stack([d[0] for d in draws]).to(self.device)
            self.turbulence[index] = torch.stack([d[1] for d in draws]).to(self.device) * self.wind_sigma
            self.wind_noise[index] = torch.stack([d[2] for d in draws]).to(self.device)
            self._set_wind(index, torch.zeros(len(rows), device=self.device))  # calm at the start (the onset)
        if SENSOR_STREAM in self.generators:
            self.sensor_noise[index] = torch.stack(
                [torch.randn(self.horizon, NOISE_WIDTH, generator=self.generators[SENSOR_STREAM][i]) for i in rows]
            ).to(self.device)
        if CAMERA_STREAM in self.generators:
            self.camera_keys[index] = torch.stack(
                [torch.randint(CAMERA_KEY_RANGE, (), generator=self.generators[CAMERA_STREAM][i]) for i in rows]
            ).to(self.device)
        if self.physics is not None:
            mask = torch.zeros(self.num_envs, dtype=torch.bool, device=self.device)
            mask[index] = True
            self.physics.reset(mask)

    def _wind_draws(self, generator: torch.Generator) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        heading = torch.rand((), generator=generator) * (2 * math.pi)
        return heading, torch.randn(3, generator=generator), torch.randn(self.horizon, 3, generator=generator)

    # ----------------------------------------------------------------------------------------------------------------
    # Per control step
    # ----------------------------------------------------------------------------------------------------------------
    def before_control_step(self, step: torch.Tensor) -> None:
        """Advance the turbulence by one control step (the envs' `step` `(N,)` of their episodes picks the noise) and
        hand the wind to the physics."""
        if WIND_STREAM not in self.generators:
            return
        step = step.to(self.device).long()
        white = self.wind_noise[self._envs, step % self.horizon]
        self.turbulence = gauss_markov_step(self.turbulence, white, self.wind_a, self.wind_sigma)
        self._set_wind(self._envs, onset(step + 1, self.onset_steps))  # the wind of the coming control step

    def _set_wind(self, index: torch.Tensor, strength: torch.Tensor) -> None:
        wind = wind_world(self.condition.wind.mean_speed_mps, self.wind_heading[index], self.turbulence[index],
                          strength)
        self.physics.wind[index] = wind

    @property
    def wind(self) -> torch.Tensor | None:
        """The world wind velocity of this control step `(N, 3)`, or None without wind."""
        return self.physics.wind if WIND_STREAM in self.generators else None

    def sensed(self, state: AirframeState, step: torch.Tensor) -> AirframeState:
        """`measure` of an `AirframeState`."""
        s = state
        return airframe_state(self.measure(flat_state(s.position, s.rotation, s.velocity, s.angular_velocity_body),
                                           step))

    def measure(self, state: torch.Tensor, step: torch.Tensor) -> torch.Tensor:
        """The state estimate `(N, 18)` (`sensors` layout) for the true airframe state `state` at the envs' `step`
        `(N,)`: delayed, then noisy. May be asked several times a control step (same answer)."""
        step = step.to(self.device).long()
        delayed = self.delay(state, step)
        noise = self.condition.sensor_noise
        if noise is None:
            return delayed
        return add_noise(delayed, self.sensor_noise[self._envs, step % self.horizon], noise)

    def camera_frames(self, sensor_data: dict, step: torch.Tensor,
                      motion: dict[str, tuple[torch.Tensor, torch.Tensor]] | None = None) -> dict:
        """The cameras' frames as the policy reads them (`sensor_data`: ManiSkill's `{camera: {"rgb": uint8 (N, H, W,
        3), "depth": int16 mm (N, H, W, 1), ...}}` at the envs' control `step` `(N,)`): each RGB frame blurred along
        its camera's rotation (`motion[camera]`: angular velocity `(N, 3)` in the camera's OpenCV frame and intrinsics
        `(N, 3, 3)`; a camera missing there is not blurred), then RGB and depth noisy. Other images pass through."""
        blur, noise = self.condition.motion_blur, self.condition.camera_noise
        out = {}
        for uid, images in sensor_data.items():
            images = dict(images)
            rgb, depth = images.get("rgb"), images.get("depth")
            if rgb is None and depth is None:
                out[uid] = images
                continue
            device = (rgb if rgb is not None else depth).device  # the render device (may differ from the sim's)
            if blur is not None and rgb is not None and motion is not None and uid in motion:
                omega, intrinsic = (t.to(device) for t in motion[uid])
                flow = rotational_flow(omega, intrinsic, rgb.shape[1], rgb.shape[2])
                images["rgb"] = rgb = motion_blur(rgb, flow, blur)
            if noise is not None:
                shape = (rgb if rgb is not None else depth).shape
                pixels = shape[1] * shape[2]
                # elements: RGB's 3 per pixel, then depth's one (a prefix of the draw: RGB alone reads the same)
                white = hashed_normals(self.camera_keys.to(device), step.to(device), camera_counter(uid),
                                       4 * pixels if depth is not None else 3 * pixels)
                if rgb is not None:
                    images["rgb"] = noisy_rgb(rgb, white[:, :3 * pixels].reshape(rgb.shape), noise)
                if depth is not None:
                    images["depth"] = noisy_depth(depth, white[:, 3 * pixels:].reshape(depth.shape), noise)
            out[uid] = images
        return out
