"""The fingers' controller: ManiSkill's mimic PD joint-position controller, an unchanged command not applied again.

The gripper command is one number (open ... closed) that the expert and most policies hold for whole phases of an
episode. Applying it is ManiSkill's `PDJointPosMimicController.set_action` (scale and clip, the mimic mapping, the
drive targets through ManiSkill's joint wrappers): about 70 us per control step on one physx_cpu env, and a step
is 5-9% cheaper without it (docs/performance.md). With `use_delta=False` and `interpolate=False` (the airframe's
configuration) the same command gives the same drive targets, which PhysX still holds, so a repeated command is
skipped. On the GPU it is always applied: comparing with the last command there would wait for the device.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from mani_skill.agents.controllers import PDJointPosMimicController, PDJointPosMimicControllerConfig


class FingerController(PDJointPosMimicController):
    config: FingerControllerConfig

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        if self.config.use_delta or self.config.interpolate:
            raise ValueError("FingerController skips repeated absolute targets: use_delta and interpolate must be False")
        self._applied: torch.Tensor | None = None  # the last command applied (physx_cpu)

    def reset(self):
        super().reset()  # the reset envs' targets become their current joint positions: the next command applies
        self._applied = None

    def set_action(self, action: torch.Tensor):
        if self.scene.gpu_sim_enabled:
            super().set_action(action)
            return
        if self._applied is not None and torch.equal(action, self._applied):
            return  # the same targets as the ones PhysX holds
        super().set_action(action)
        self._applied = action.clone()


@dataclass
class FingerControllerConfig(PDJointPosMimicControllerConfig):
    controller_cls = FingerController
