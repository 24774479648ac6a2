"""A body's pose as ManiSkill's `Pose`, read cheaply where the simulation holds one env.

ManiSkill's batched getters (`Actor.pose`, `Link.pose`) serve every backend: on physx_cpu they build the `(1, 7)`
tensor from a list of SAPIEN poses through generic conversions, 25-50 microseconds per read. The step context reads
four poses every control step (tool centre point, both fingers, the object) and the object's velocity, so on
physx_cpu they are read straight from the one SAPIEN entity (about 8 microseconds); on physx_cuda ManiSkill's getter
is already one slice of the batched body data.
"""

from __future__ import annotations

import numpy as np
import torch
from mani_skill.utils.structs import Actor, Link, Pose


def raw_pose_of(body: Actor | Link) -> torch.Tensor:
    """`body.pose.raw_pose`, `(N, 7)` (position, wxyz); on physx_cpu without ManiSkill's list conversions."""
    if body.scene.gpu_sim_enabled or len(body._objs) != 1:
        return body.pose.raw_pose
    pose = _sapien_pose(body)
    return torch.from_numpy(np.concatenate([pose.p, pose.q]).reshape(1, 7))  # (the batch axis: numpy's is cheaper)


def _sapien_pose(body: Actor | Link):
    """The SAPIEN pose of `body`'s one entity (physx_cpu)."""
    obj = body._objs[0]
    return obj.entity_pose if isinstance(body, Link) else obj.pose  # a link component, or an actor's entity


def pose_of(body: Actor | Link) -> Pose:
    """`body.pose`, the same `(N, 7)` numbers; on physx_cpu without ManiSkill's list conversions."""
    if body.scene.gpu_sim_enabled or len(body._objs) != 1:
        return body.pose
    return Pose(raw_pose=raw_pose_of(body))


def linear_velocity_of(body: Actor) -> torch.Tensor:
    """`body.linear_velocity`, `(N, 3)`; on physx_cpu the one SAPIEN body's own array (ManiSkill's getter builds it
    through a list and a fresh tensor)."""
    if body.scene.gpu_sim_enabled or len(body._bodies) != 1:
        return body.linear_velocity
    return torch.from_numpy(body._bodies[0].linear_velocity[None])


def raw_quats_of(bodies: list[Actor | Link]) -> torch.Tensor:
    """The orientations (wxyz) of `bodies`, `(N, len(bodies), 4)`; on physx_cpu one array from the SAPIEN entities."""
    if any(b.scene.gpu_sim_enabled or len(b._objs) != 1 for b in bodies):
        return torch.stack([raw_pose_of(b)[:, 3:] for b in bodies], 1)
    # one concatenation and a reshape: `np.stack` and a torch view cost twice as much (a read every control step)
    return torch.from_numpy(np.concatenate([_sapien_pose(b).q for b in bodies]).reshape(1, len(bodies), 4))
