"""Everything that is simulated: platform constants, the flight controller, agents, scenes, objects and envs.

Importing this package registers the agents (`aero_gripper`, `aero_arm`) and the envs (`AeroFly-v1`, `AeroPick-v1`,
`AeroPlace-v1`, `AeroNav-v1`, `AeroOpen-v1`, `AeroClose-v1`, `AeroSequential-v1`) with ManiSkill.
"""

from . import agents, flight_test, skills  # noqa: F401  (registration side effects)
from .platforms import PLATFORMS, get_platform

__all__ = ["PLATFORMS", "get_platform"]
