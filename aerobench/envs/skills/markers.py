"""Visual-only goal markers: where a skill's goal is a point only the simulator knows, the scene shows it.

Place's goal is a random point on its support and Nav's target a point in the air near a named place; a policy of
the `vision` input tier (`aerobench.tiers`: cameras, proprioception and the instruction only) could not know either.
So each env shows the active goals as markers that the cameras see and the instruction names ("... on the marked
spot of the side counter"): a flat green disc the size of Place's goal region on the support, a small green sphere
at a named Nav target. Markers have no collision shape and are kinematic, so the simulation, the expert and the
`privileged` task state are what they were without them (tests/envs/test_markers.py); only the pictures change.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import sapien
import torch
from mani_skill.utils.structs import Actor, Pose

from .starts import PARKING_DEPTH_M

# No object, fixture or furniture colour of the scenes is a saturated green (objects.OBJECTS, scenes.furniture), so
# the mark cannot be taken for one of them.
MARKER_RGB = (0.10, 0.85, 0.20)
DISC_LIFT_M = 0.001  # the disc's underside above the support's surface: drawn on it, not in it
_X_TO_Z = (math.cos(-math.pi / 4), 0.0, math.sin(-math.pi / 4), 0.0)  # SAPIEN's cylinder axis is x; a disc lies in xy


@dataclass(frozen=True)
class MarkerShape:
    """`disc`: a flat cylinder lying on a support (`radius_m`, `thickness_m`); `sphere`: a ball (`radius_m`)."""

    kind: str
    radius_m: float
    thickness_m: float = 0.0

    def __post_init__(self):
        if self.kind not in ("disc", "sphere"):
            raise ValueError(f"a marker is a disc or a sphere, got {self.kind!r}")

    @property
    def lift_m(self) -> float:
        """The marker's centre above the goal point it marks (a disc's centre sits half its thickness up)."""
        return DISC_LIFT_M + self.thickness_m / 2 if self.kind == "disc" else 0.0


def build_marker(scene, shape: MarkerShape, name: str) -> Actor:
    """One kinematic, visual-only marker actor per parallel env (parked under the floor until it is placed)."""
    builder = scene.create_actor_builder()
    if shape.kind == "disc":
        builder.add_cylinder_visual(pose=sapien.Pose(q=list(_X_TO_Z)), radius=shape.radius_m,
                                    half_length=shape.thickness_m / 2, material=MARKER_RGB)
    else:
        builder.add_sphere_visual(radius=shape.radius_m, material=MARKER_RGB)
    builder.initial_pose = sapien.Pose(p=[0.0, 0.0, PARKING_DEPTH_M])
    return builder.build_kinematic(name=name)


def place_marker(marker: Actor, shape: MarkerShape, position: torch.Tensor, shown: torch.Tensor) -> None:
    """Put the marker of the envs being reset at `position` `(M, 3)` (the goal point), or under the floor where
    `shown` `(M,)` is False (an env whose goal is shown by another marker, or has none)."""
    parked = torch.tensor([0.0, 0.0, PARKING_DEPTH_M], device=position.device).expand_as(position)
    p = torch.where(shown[:, None], position + torch.tensor([0.0, 0.0, shape.lift_m], device=position.device), parked)
    marker.set_pose(Pose.create_from_pq(p=p))
