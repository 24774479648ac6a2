"""Arm platform: X500 with a 3-DoF arm (shoulder pitch, elbow pitch, wrist roll) and the UMI gripper at its end."""

from __future__ import annotations

import sapien
from mani_skill.agents.registration import register_agent

from ..platforms import ARM_PLATFORM
from .airframe import _Q_X, _Q_X_TO_Y, GRIPPER_COLOR, AerialAgent, add_box

ARM_COLOR = (0.3, 0.32, 0.36)


@register_agent()
class AeroArmPlatform(AerialAgent):
    """Spec appendix "Robot platforms", arm platform: grasp point 0.47 m ahead and 0.02 m below in the working pose.

    Action: `[u_x, u_y, u_z, u_psi, q_shoulder, q_elbow, q_wrist, u_g]` in [-1, 1]; the arm entries are joint targets
    scaled to the joint limits, u_g as on the gripper platform. At zero wrist roll the fingers close horizontally
    (the fridge's vertical bar), at 90 degrees vertically (the drawer's handle).
    """

    uid = "aero_arm"
    platform = ARM_PLATFORM
    arm_joint_names = tuple(j.name for j in ARM_PLATFORM.arm.joints)
    grasp_link_name = "wrist"
    _tcp_offset_in_grasp_link = (ARM_PLATFORM.arm.wrist_to_grasp_m, 0.0, 0.0)

    def _build_manipulator(self, builder, airframe) -> None:
        arm = self.platform.arm
        t = arm.link_thickness_m / 2
        shoulder_j, elbow_j, wrist_j = arm.joints
        segments = (
            # link name, joint, parent, joint origin in the parent link, joint frame, length, mass
            ("upper_arm", shoulder_j, airframe, arm.shoulder_position_m, _Q_X_TO_Y, arm.upper_arm_length_m, arm.upper_arm_mass_kg),
            ("forearm", elbow_j, None, (arm.upper_arm_length_m, 0.0, 0.0), _Q_X_TO_Y, arm.forearm_length_m, arm.forearm_mass_kg),
            ("wrist", wrist_j, None, (arm.forearm_length_m, 0.0, 0.0), _Q_X, arm.wrist_to_grasp_m, arm.wrist_mass_kg),
        )
        parent = airframe
        for name, joint, _, origin, quat, length, mass in segments:
            link = builder.create_link_builder(parent)
            link.set_name(name)
            link.set_joint_name(joint.name)
            link.set_joint_properties(
                "revolute",
                limits=[[joint.lower_rad, joint.upper_rad]],
                pose_in_parent=sapien.Pose(p=list(origin), q=quat),
                pose_in_child=sapien.Pose(q=quat),
            )
            if name == "wrist":  # the palm: a short block a third of the way to the grasp point
                com = (length / 3, 0.0, 0.0)
                add_box(link, com, (arm.palm_half_length_m, 0.035, 0.015), GRIPPER_COLOR)
            else:
                com = (length / 2, 0.0, 0.0)
                add_box(link, com, (length / 2, t, t), ARM_COLOR)
            ix = mass * (2 * t) ** 2 / 6
            iyz = mass * (length**2 + (2 * t) ** 2) / 12
            link.set_mass_and_inertia(mass, sapien.Pose(p=list(com)), [ix, iyz, iyz])
            parent = link
        # Fingers: pads from 3 to 15 cm past the wrist joint, the grasp point 3 cm inside their tips.
        self._add_fingers(builder, parent, (0.03, 0.0, 0.0), along_x=True)


__all__ = ["AeroArmPlatform"]
