"""The free-flying airframe as six virtual joints from the world (spec Sec. 3.2, "GPU-parallel flight").

Joint order: prismatic x, y, z (world axes) then revolute yaw (world z), pitch (yawed y), roll (body x), so the
airframe rotation is R = Rz(yaw) Ry(pitch) Rx(roll) and the joints pivot about the airframe centre O. A world wrench
W = (F, tau_O) about O becomes joint efforts Q = J^T W, where J maps joint velocities to (v_O, omega).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import torch

NUM_VIRTUAL_JOINTS = 6
VIRTUAL_JOINT_NAMES = ("root_x", "root_y", "root_z", "root_yaw", "root_pitch", "root_roll")


def joint_columns(indices: Sequence[int], device: torch.device | str) -> slice | torch.Tensor:
    """The columns `indices` of `(N, J)` joint vectors: a slice where they are one ascending run (a view, read at
    no gather's cost: a per-step read of a few columns by a list costs microseconds), else an index tensor."""
    idx = [int(i) for i in indices]
    if idx and idx == list(range(idx[0], idx[-1] + 1)):
        return slice(idx[0], idx[-1] + 1)
    return torch.tensor(idx, dtype=torch.long, device=device)


@dataclass
class AirframeState:
    """Measured rigid-body state of the airframe, all `(N, ...)` tensors in SI units.

    position/velocity are of the airframe centre O in the world frame; rotation maps body to world;
    angular_velocity_body is omega expressed in the body frame.
    """

    position: torch.Tensor
    velocity: torch.Tensor
    rotation: torch.Tensor
    angular_velocity_body: torch.Tensor

    @property
    def yaw(self) -> torch.Tensor:
        return torch.atan2(self.rotation[..., 1, 0], self.rotation[..., 0, 0])


def airframe_state_from_joints(q: torch.Tensor, qd: torch.Tensor, origin: torch.Tensor | None = None) -> AirframeState:
    """Rigid-body state from the six virtual joint positions `q` and velocities `qd` (each `(N, 6)`).

    Closed forms of R = Rz(psi) Ry(theta) Rx(phi) and of the ZYX Euler-rate map, written out element by element:
    this runs at every physics step, and on a CPU with one env a few elementwise ops cost less than 3x3 products.
    `origin` is the world position of the articulation root (the per-env scene offset is not included).
    """
    cy, sy = torch.cos(q[:, 3]), torch.sin(q[:, 3])
    cp, sp = torch.cos(q[:, 4]), torch.sin(q[:, 4])
    cr, sr = torch.cos(q[:, 5]), torch.sin(q[:, 5])
    R = torch.stack(
        [
            cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr,
            sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr,
            -sp, cp * sr, cp * cr,
        ],
        dim=-1,
    ).view(-1, 3, 3)
    yaw_rate, pitch_rate, roll_rate = qd[:, 3], qd[:, 4], qd[:, 5]
    omega_body = torch.stack(
        [
            roll_rate - yaw_rate * sp,
            pitch_rate * cr + yaw_rate * cp * sr,
            -pitch_rate * sr + yaw_rate * cp * cr,
        ],
        dim=-1,
    )
    position = q[:, :3] if origin is None else q[:, :3] + origin
    return AirframeState(position, qd[:, :3], R, omega_body)


def joint_efforts_from_wrench(q: torch.Tensor, force_world: torch.Tensor, torque_world: torch.Tensor) -> torch.Tensor:
    """Q = J^T W for a wrench about the pivot O: forces on the sliders, the torque projected on each rotation axis.

    The axes in the world frame are e_z (yaw), Rz(psi) e_y (pitch) and Rz(psi) Ry(theta) e_x (roll).
    """
    cy, sy = torch.cos(q[:, 3]), torch.sin(q[:, 3])
    cp, sp = torch.cos(q[:, 4]), torch.sin(q[:, 4])
    tx, ty, tz = torque_world[:, 0], torque_world[:, 1], torque_world[:, 2]
    rotational = torch.stack([tz, -sy * tx + cy * ty, cp * (cy * tx + sy * ty) - sp * tz], dim=-1)
    return torch.cat([force_world, rotational], dim=-1)
