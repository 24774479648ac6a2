"""LeRobot plugin entry: importing it registers aerobench's LeRobot types with `lerobot-train` / `lerobot-eval`.

- the `aerobench` EnvConfig (`--env.type=aerobench`, aerobench.envs.lerobot_env);
- the tiny pi policy types `pi0_tiny` and `pi05_tiny` (aerobench.policies.pi_tiny), which `--policy.path` folders
  written by `aerobench pi-init --variant tiny` name in their config.json.
"""

from aerobench.envs.lerobot_env import AerobenchEnvConfig  # noqa: F401
from aerobench.policies.pi_tiny import PI0TinyConfig, PI05TinyConfig  # noqa: F401
