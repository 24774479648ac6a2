"""LeRobot integration: the `aerobench` env type for `lerobot-eval` / `lerobot-train --env.type=aerobench`.

`AerobenchEnvConfig` is registered in LeRobot's `EnvConfig` registry; its `task` names a skill or a chain of a task
setting as `"<Setting>/<skill or chain>"` (e.g. `TidyHouse/pick`, `PackageDelivery/deliver`). Each LeRobot env is
one `physx_cpu` aerobench env wrapped by `LeRobotAdapter`, which speaks LeRobot's gym contract:
`obs = {"pixels": {camera: HWC uint8, "<camera>_depth": packed depth HWC uint8}, "agent_pos": float32 state,
"environment_state": float32 task state}`, `info["is_success"]`, `task_description`. The feature map puts them where
the dataset export writes them: `observation.images.<camera>`, `observation.depth.<camera>` (LeRobot's eval loop
names every pixel key `observation.images.<key>`; the env's preprocessor, `DepthKeys`, renames the depth ones),
`observation.state` and `observation.environment_state`. So every checkpoint trained on an aerobench dataset finds
the inputs it names, whatever its tier (`aerobench.tiers`): the env offers both, the policy reads what it was
trained on. LeRobot finds this module through the `lerobot_env_aerobench` plugin distribution.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import gymnasium as gym
import numpy as np
import torch
from lerobot.configs import FeatureType, PolicyFeature
from lerobot.envs.configs import EnvConfig
from lerobot.processor import ObservationProcessorStep, PolicyProcessorPipeline
from lerobot.utils.constants import ACTION, OBS_ENV_STATE, OBS_IMAGES, OBS_STATE

from ..depth import encode_depth_mm
from .conditions import resolve_condition
from .observations import STATE_DIM, task_state_field_names
from .platforms import get_platform
from .tasks import DEFAULT_PLATFORM, SKILLS, get_setting

CAMERAS = ("drone_front", "drone_hand", "drone_own")
DEPTH_PIXELS = "_depth"  # a camera's packed depth among the env's pixels: "<camera>_depth"
OBS_DEPTH = "observation.depth"  # the dataset's depth key (export.features.depth_key)
IMAGE_SHAPE = (128, 128, 3)
ENV_IDS = {
    "pick": "AeroPick-v1",
    "place": "AeroPlace-v1",
    "nav": "AeroNav-v1",
    "open": "AeroOpen-v1",
    "close": "AeroClose-v1",
}


def parse_task(task: str) -> tuple[str, str, dict]:
    """`"<Setting>/<skill or chain>"` -> (gym id, setting, extra kwargs); unknown names are one-line errors."""
    if not task or "/" not in task:
        raise ValueError(f"task must look like 'TidyHouse/pick' or 'PackageDelivery/deliver', got {task!r}")
    setting_name, what = task.split("/", 1)
    setting = get_setting(setting_name)
    if what in SKILLS:
        setting.check_skill(what)
        return ENV_IDS[what], setting.name, {}
    setting.chain(what)  # raises with the valid chain names
    return "AeroSequential-v1", setting.name, {"chain": what}


def default_platform(task: str) -> str:
    _, setting, extra = parse_task(task)
    if "chain" in extra:
        return get_setting(setting).chain_platform
    return DEFAULT_PLATFORM[task.split("/", 1)[1]]


class LeRobotAdapter(gym.Wrapper):
    """One aerobench env (num_envs = 1) as an unbatched numpy gym env in LeRobot's observation format."""

    def __init__(self, env: gym.Env, max_episode_steps: int):
        super().__init__(env)
        base = env.unwrapped
        state_dim = base.agent.get_proprioception()["state"].shape[-1]
        task_dim = len(task_state_field_names(with_arm=base.platform.arm is not None))
        pixels = {key: gym.spaces.Box(0, 255, IMAGE_SHAPE, dtype=np.uint8) for key in pixel_keys()}
        self.observation_space = gym.spaces.Dict(
            {
                "pixels": gym.spaces.Dict(pixels),
                "agent_pos": gym.spaces.Box(-np.inf, np.inf, (state_dim,), dtype=np.float32),
                "environment_state": gym.spaces.Box(-np.inf, np.inf, (task_dim,), dtype=np.float32),
            }
        )
        dim = base.platform.action_dim
        self.action_space = gym.spaces.Box(-1.0, 1.0, (dim,), dtype=np.float32)
        self._max_episode_steps = max_episode_steps
        self.metadata = {**getattr(env, "metadata", {}), "render_fps": 20}

    def _convert(self, obs) -> dict:
        sensors = obs["sensor_data"]
        pixels = {c: sensors[c]["rgb"][0].cpu().numpy().astype(np.uint8) for c in CAMERAS}
        for c in CAMERAS:
            depth = sensors[c]["depth"][0, ..., 0].cpu().numpy().clip(0, np.iinfo(np.uint16).max).astype(np.uint16)
            pixels[c + DEPTH_PIXELS] = encode_depth_mm(depth)
        return {"pixels": pixels, "agent_pos": obs["agent"]["state"][0].cpu().numpy().astype(np.float32),
                "environment_state": self.env.unwrapped.task_state()[0].cpu().numpy().astype(np.float32)}

    def reset(self, *, seed=None, options=None):
        obs, info = self.env.reset(seed=seed, options=options)
        return self._convert(obs), self._info(info)

    def step(self, action):
        action = torch.as_tensor(np.asarray(action, dtype=np.float32))[None]
        obs, reward, terminated, truncated, info = self.env.step(action)
        return (
            self._convert(obs),
            float(reward[0]) if torch.is_tensor(reward) else float(reward),
            bool(terminated[0]),
            bool(truncated[0]) if torch.is_tensor(truncated) else bool(truncated),
            self._info(info),
        )

    @staticmethod
    def _info(info: dict) -> dict:
        out = {}
        for key, value in info.items():
            if torch.is_tensor(value) and value.numel() == 1:
                out[key] = value.item()
            elif torch.is_tensor(value):
                out[key] = value[0].cpu().numpy()
        out["is_success"] = bool(info["success"][0]) if "success" in info else False
        return out

    def task_description(self) -> str:
        return self.env.unwrapped.get_instruction(0)

    def task(self) -> str:
        return self.task_description()

    def render(self):
        frame = self.env.render()
        return frame[0].cpu().numpy() if torch.is_tensor(frame) else frame


def pixel_keys() -> list[str]:
    """The env's pixel keys: each camera's RGB, then each camera's packed depth."""
    return [*CAMERAS, *(c + DEPTH_PIXELS for c in CAMERAS)]


class DepthKeys(ObservationProcessorStep):
    """LeRobot's eval loop names every pixel key `observation.images.<key>`; aerobench datasets (and the policies
    trained on them) name a camera's depth `observation.depth.<camera>`. This env preprocessor step renames them."""

    def observation(self, observation):
        prefix = f"{OBS_IMAGES}."
        return {(f"{OBS_DEPTH}.{k[len(prefix):-len(DEPTH_PIXELS)]}" if k.startswith(prefix) and k.endswith(DEPTH_PIXELS)
                 else k): v for k, v in observation.items()}

    def transform_features(self, features):
        return features


def make_lerobot_env(
    task: str,
    episode_length: int | None = None,
    object: str | None = None,  # noqa: A002
    platform: str | None = None,
    controller: str = "payload-aware",
    condition: str | None = None,
) -> LeRobotAdapter:
    import aerobench.envs  # noqa: F401  (registers the envs)

    env_id, setting, extra = parse_task(task)
    kwargs = dict(setting=setting, obs_mode="rgbd", render_mode="rgb_array", controller=controller, **extra)
    if object:
        kwargs["object"] = object
    if platform:
        kwargs["platform"] = platform
    if episode_length:
        kwargs["max_episode_steps"] = episode_length
    if condition:
        kwargs["condition"] = condition
    env = gym.make(env_id, **kwargs)
    return LeRobotAdapter(env, getattr(env, "_max_episode_steps", None) or episode_length or 1000)


class EnvConfigError(Exception):
    """A bad `--env.*` value. Not a ValueError on purpose: draccus, which parses LeRobot's command lines, wraps a
    ValueError from a config's constructor into "Couldn't instantiate class ..." with two chained tracebacks; this one
    it lets through, so the traceback ends with aerobench's own one-line message."""


@EnvConfig.register_subclass("aerobench")
@dataclass
class AerobenchEnvConfig(EnvConfig):
    """`--env.type=aerobench --env.task=TidyHouse/pick [--env.object=tomato_soup_can] [--env.platform=gripper]
    [--env.condition=wind_gusty_3ms,motor_lag]` (evaluation conditions, `aerobench conditions`)."""

    task: str | None = "TidyHouse/pick"
    fps: int = 20
    episode_length: int | None = None
    object: str | None = None
    platform: str | None = None
    controller: str = "payload-aware"
    condition: str | None = None
    features: dict[str, PolicyFeature] = field(default_factory=dict)
    features_map: dict[str, str] = field(default_factory=dict)

    def __post_init__(self):
        try:
            parse_task(self.task)
            platform = get_platform(self.platform or default_platform(self.task))
        except ValueError as e:
            raise EnvConfigError(f"--env.task / --env.platform: {e}") from None
        try:
            resolve_condition(self.condition)
        except ValueError as e:
            raise EnvConfigError(f"--env.condition: {e}") from None
        with_arm = platform.arm is not None
        state_dim = STATE_DIM + (6 if with_arm else 0)
        self.features = {
            ACTION: PolicyFeature(type=FeatureType.ACTION, shape=(platform.action_dim,)),
            "agent_pos": PolicyFeature(type=FeatureType.STATE, shape=(state_dim,)),
            "environment_state": PolicyFeature(type=FeatureType.ENV, shape=(len(task_state_field_names(with_arm)),)),
            **{f"pixels/{k}": PolicyFeature(type=FeatureType.VISUAL, shape=IMAGE_SHAPE) for k in pixel_keys()},
        }
        self.features_map = {
            ACTION: ACTION,
            "agent_pos": OBS_STATE,
            "environment_state": OBS_ENV_STATE,
            **{f"pixels/{c}": f"{OBS_IMAGES}.{c}" for c in CAMERAS},
            **{f"pixels/{c}{DEPTH_PIXELS}": f"{OBS_DEPTH}.{c}" for c in CAMERAS},
        }

    def get_env_processors(self):
        return PolicyProcessorPipeline(steps=[DepthKeys()]), PolicyProcessorPipeline(steps=[])

    @property
    def gym_kwargs(self) -> dict:
        return {
            "task": self.task,
            "episode_length": self.episode_length,
            "object": self.object,
            "platform": self.platform,
            "controller": self.controller,
            "condition": self.condition,
        }

    def create_envs(self, n_envs: int, use_async_envs: bool = False):
        kwargs = self.gym_kwargs

        def make_one():
            return make_lerobot_env(**kwargs)

        # As LeRobot's own envs: same-step autoreset (the rollout masks finished envs itself), and a process per env
        # when asked for async envs (each is a separate SAPIEN scene; forkserver because SAPIEN does not survive fork)
        extra = {"context": "forkserver"} if use_async_envs and n_envs > 1 else {}
        vec_cls = gym.vector.AsyncVectorEnv if extra else gym.vector.SyncVectorEnv
        vec = vec_cls([make_one for _ in range(n_envs)], autoreset_mode=gym.vector.AutoresetMode.SAME_STEP, **extra)
        return {self.type: {0: vec}}
