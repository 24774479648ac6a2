"""ManiSkill agents of the two aerial platforms (importing this registers `aero_gripper` and `aero_arm`)."""

from .airframe import AerialAgent, NonFiniteActionError
from .arm_platform import AeroArmPlatform
from .gripper_platform import AeroGripperPlatform

AGENT_UIDS = {"gripper": AeroGripperPlatform.uid, "arm": AeroArmPlatform.uid}

__all__ = ["AGENT_UIDS", "AerialAgent", "AeroArmPlatform", "AeroGripperPlatform", "NonFiniteActionError"]
