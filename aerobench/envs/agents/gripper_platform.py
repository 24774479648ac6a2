"""Gripper platform: X500 with a fixed downward 1-DoF parallel gripper (long UMI fingers) below the airframe."""

from __future__ import annotations

from mani_skill.agents.registration import register_agent

from ..platforms import GRIPPER_PALM_Z_M, GRIPPER_PLATFORM
from .airframe import GRIPPER_COLOR, AerialAgent, add_box


@register_agent()
class AeroGripperPlatform(AerialAgent):
    """Spec appendix "Robot platforms", gripper platform: grasp point 0.28 m below the airframe centre.

    Action: `[u_x, u_y, u_z, u_psi, u_g]` in [-1, 1]; u_g = -1 closes the fingers, +1 opens them to 110 mm.
    """

    uid = "aero_gripper"
    platform = GRIPPER_PLATFORM
    grasp_link_name = "airframe"
    _tcp_offset_in_grasp_link = GRIPPER_PLATFORM.grasp_point_m

    def _build_manipulator(self, builder, airframe) -> None:
        # Adapter mast and palm are rigid parts of the airframe link (their masses are airframe components).
        mast_top, mast_bottom = -0.02, GRIPPER_PALM_Z_M + 0.02
        add_box(airframe, (0, 0, (mast_top + mast_bottom) / 2), (0.012, 0.012, (mast_top - mast_bottom) / 2), GRIPPER_COLOR)
        add_box(airframe, (0, 0, GRIPPER_PALM_Z_M + 0.01), (0.02, 0.065, 0.01), GRIPPER_COLOR)
        self._add_fingers(builder, airframe, (0.0, 0.0, GRIPPER_PALM_Z_M), along_x=False)


__all__ = ["AeroGripperPlatform"]
