"""aerobench: a LeRobot-native benchmark suite for aerial manipulation (spec: AeroManip-VLA).

Importing `aerobench.envs` registers the ManiSkill agents and envs.
"""

__version__ = "0.1.0"
