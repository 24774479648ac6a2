"""The fingers' controller: ManiSkill's mimic PD joint-position controller, an unchanged command not applied again.

The gripper command is one number (open ... closed) that the expert and most policies hold for whole phases of an
episode. Applying it is ManiSkill's `PDJointPosMimicController.set_action` (scale and clip, the mimic mapping, the
drive targets through ManiSkill's joint wrappers): about 70 us per control step on one physx_cpu env, and a step
is 5-9% cheaper without it (docs/performance.md). With `use_delta=False` and `interpolate=False` (the airframe's
configuration) the same command gives the same drive targets, so a repeated command is skipped while PhysX still
holds the targets it set. On the GPU it is always applied: comparing with the last command there would wait for the
device.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import torch
from mani_skill.agents.controllers import PDJointPosMimicController, PDJointPosMimicControllerConfig


class FingerController(PDJointPosMimicController):
    config: FingerControllerConfig

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        if self.config.use_delta or self.config.interpolate:
            raise ValueError("FingerController skips repeated absolute targets: use_delta and interpolate must be False")
        # physx_cpu: the PhysX joints themselves, to confirm that they still hold the targets applied last (another
        # control mode's controller, or any other code, may have moved them since)
        self._cpu_joints = None if self.scene.gpu_sim_enabled else [joint._objs[0] for joint in self.joints]
        self._applied: tuple[list[float], list[float]] | None = None  # the last command and its drive targets
        self._dim = self.single_action_space.shape[0]

    def reset(self):
        super().reset()  # the reset envs' targets become their current joint positions: the next command applies
        self._applied = None

    def before_simulation_step(self):
        """Nothing between physics steps: the targets are absolute and not interpolated, and PhysX's drive holds them
        (ManiSkill's own hook only counts physics steps for its interpolation). The airframe's agent calls the body
        controller alone at 240 Hz for that reason."""

    def set_action(self, action: torch.Tensor):
        if self._cpu_joints is None or action.shape != (1, self._dim):
            super().set_action(action)  # (ManiSkill's check names a wrong shape)
            self._applied = None
            return
        self.set_action_values(action.tolist()[0])

    def set_action_values(self, values: Sequence[float]) -> None:
        """`set_action` for the one env of physx_cpu, from its command as host floats (`AerialAgent.set_action`)."""
        joints, applied, values = self._cpu_joints, self._applied, list(values)
        if (applied is not None and applied[0] == values
                and all(float(j.get_drive_target()[0]) == t for j, t in zip(joints, applied[1]))):
            return  # PhysX holds the very targets this command gives
        super().set_action(torch.tensor([values], dtype=torch.float32, device=self.device))
        self._applied = (values, [float(j.get_drive_target()[0]) for j in joints])


@dataclass
class FingerControllerConfig(PDJointPosMimicControllerConfig):
    controller_cls = FingerController
