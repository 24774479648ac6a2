"""LeRobot integration: the `aerobench` env type for `lerobot-eval` / `lerobot-train --env.type=aerobench`.

`AerobenchEnvConfig` is registered in LeRobot's `EnvConfig` registry; its `task` names a skill or a chain of a task
setting as `"<Setting>/<skill or chain>"` (e.g. `TidyHouse/pick`, `PackageDelivery/deliver`). Each LeRobot env is
one `physx_cpu` aerobench env wrapped by `LeRobotAdapter`, which speaks LeRobot's gym contract:
`obs = {"pixels": {camera: HWC uint8}, "agent_pos": float32 state}`, `info["is_success"]`, `task_description`.
The feature map puts cameras at `observation.images.<camera>` and the state at `observation.state`, the same keys
the dataset export writes. LeRobot finds this module through the `lerobot_env_aerobench` plugin distribution.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import gymnasium as gym
import numpy as np
import torch
from lerobot.configs import FeatureType, PolicyFeature
from lerobot.envs.configs import EnvConfig
from lerobot.utils.constants import ACTION, OBS_IMAGES, OBS_STATE

from .platforms import get_platform
from .tasks import DEFAULT_PLATFORM, SKILLS, get_setting

CAMERAS = ("drone_front", "drone_hand", "drone_own")
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
        self.observation_space = gym.spaces.Dict(
            {
                "pixels": gym.spaces.Dict(
                    {c: gym.spaces.Box(0, 255, (128, 128, 3), dtype=np.uint8) for c in CAMERAS}
                ),
                "agent_pos": gym.spaces.Box(-np.inf, np.inf, (state_dim,), dtype=np.float32),
            }
        )
        dim = base.platform.action_dim
        self.action_space = gym.spaces.Box(-1.0, 1.0, (dim,), dtype=np.float32)
        self._max_episode_steps = max_episode_steps
        self.metadata = {**getattr(env, "metadata", {}), "render_fps": 20}

    def _convert(self, obs) -> dict:
        sensors = obs["sensor_data"]
        pixels = {c: sensors[c]["rgb"][0].cpu().numpy().astype(np.uint8) for c in CAMERAS}
        return {"pixels": pixels, "agent_pos": obs["agent"]["state"][0].cpu().numpy().astype(np.float32)}

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


def make_lerobot_env(
    task: str,
    episode_length: int | None = None,
    object: str | None = None,  # noqa: A002
    platform: str | None = None,
    controller: str = "payload-aware",
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
    env = gym.make(env_id, **kwargs)
    return LeRobotAdapter(env, getattr(env, "_max_episode_steps", None) or episode_length or 1000)


@EnvConfig.register_subclass("aerobench")
@dataclass
class AerobenchEnvConfig(EnvConfig):
    """`--env.type=aerobench --env.task=TidyHouse/pick [--env.object=tomato_soup_can] [--env.platform=gripper]`."""

    task: str | None = "TidyHouse/pick"
    fps: int = 20
    episode_length: int | None = None
    object: str | None = None
    platform: str | None = None
    controller: str = "payload-aware"
    features: dict[str, PolicyFeature] = field(default_factory=dict)
    features_map: dict[str, str] = field(default_factory=dict)

    def __post_init__(self):
        parse_task(self.task)
        platform = get_platform(self.platform or default_platform(self.task))
        state_dim = 19 + (6 if platform.arm else 0)
        self.features = {
            ACTION: PolicyFeature(type=FeatureType.ACTION, shape=(platform.action_dim,)),
            "agent_pos": PolicyFeature(type=FeatureType.STATE, shape=(state_dim,)),
            **{f"pixels/{c}": PolicyFeature(type=FeatureType.VISUAL, shape=(128, 128, 3)) for c in CAMERAS},
        }
        self.features_map = {
            ACTION: ACTION,
            "agent_pos": OBS_STATE,
            **{f"pixels/{c}": f"{OBS_IMAGES}.{c}" for c in CAMERAS},
        }

    @property
    def gym_kwargs(self) -> dict:
        return {
            "task": self.task,
            "episode_length": self.episode_length,
            "object": self.object,
            "platform": self.platform,
            "controller": self.controller,
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
