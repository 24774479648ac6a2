"""LeRobot plugin entry: importing it registers the `aerobench` EnvConfig (see aerobench.envs.lerobot_env)."""

from aerobench.envs.lerobot_env import AerobenchEnvConfig  # noqa: F401
