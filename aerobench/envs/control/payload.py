"""Payload-aware switches (spec Sec. 3.2 "Payload-aware compensation" and appendix "Payload-Aware Flight Control").

Run once per control step with what the simulator knows about the carried object:
- after `grasp_steps_for_payload` (three) consecutive grasped control steps, m_hat <- m0 + m_obj and the attitude
  gains rise from (k_R, k_w) to (12, 1.2);
- once the placement support carries the object ("set down"), m_hat <- m0 and the vertical integral xi_z resets (on
  the step the support takes the load), so there is no excess thrust after release. The caller flags only the
  placement support: an object still resting on the support it is being lifted from is not "set down", so the
  feedforward helps lift it off;
- when the grasp is lost or released, the controller returns to the unloaded mass and the nominal gains.
The "nominal" controller (for ablations) keeps m_hat = m0 and the nominal gains throughout.
"""

from __future__ import annotations

from dataclasses import replace
from enum import StrEnum

import torch

from .flight import FlightMemory, FlightParams


class ControllerMode(StrEnum):
    PAYLOAD_AWARE = "payload-aware"
    NOMINAL = "nominal"

    @classmethod
    def parse(cls, name: str) -> ControllerMode:
        try:
            return cls(name)
        except ValueError:
            raise ValueError(f"unknown controller {name!r}; valid controllers: {', '.join(m.value for m in cls)}") from None


def update_payload_estimate(
    memory: FlightMemory,
    params: FlightParams,
    is_grasped: torch.Tensor,
    is_set_down: torch.Tensor,
    object_mass: torch.Tensor,
    mode: ControllerMode = ControllerMode.PAYLOAD_AWARE,
) -> FlightMemory:
    """Apply the payload switches for one control step; all inputs are `(N,)` tensors."""
    grasp_steps = torch.where(is_grasped, memory.grasp_steps + 1, torch.zeros_like(memory.grasp_steps))
    if mode is ControllerMode.NOMINAL:
        return replace(memory, grasp_steps=grasp_steps, supported=is_set_down)

    g = params.gains
    loaded = memory.payload_active & is_grasped  # a lost grasp drops the payload estimate
    loaded = loaded | (is_grasped & (grasp_steps >= g.grasp_steps_for_payload))
    carried = loaded & ~is_set_down
    mass_hat = torch.where(carried, params.mass + object_mass, torch.full_like(memory.mass_hat, params.mass))
    k_R = torch.where(loaded, torch.full_like(memory.k_R, g.payload_k_R), torch.full_like(memory.k_R, g.k_R))
    k_w = torch.where(loaded, torch.full_like(memory.k_w, g.payload_k_w), torch.full_like(memory.k_w, g.k_w))
    set_down = loaded & is_set_down & ~memory.supported
    xi = memory.xi.clone()
    xi[..., 2] = torch.where(set_down, torch.zeros_like(xi[..., 2]), xi[..., 2])
    return replace(
        memory,
        xi=xi,
        mass_hat=mass_hat,
        k_R=k_R,
        k_w=k_w,
        grasp_steps=grasp_steps,
        payload_active=loaded,
        supported=is_set_down,
    )
