"""Contact forces the skills need, read once per control step for every env.

On the GPU each quantity is a ManiSkill contact query; on the CPU one pass over PhysX's contact list fills them all
(ManiSkill's per-pair helpers would walk the list once per pair). Forces are from the last physics step of the
control step (impulse / dt), in newtons, world frame; the force on a body is what the others push it with.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from mani_skill.utils.structs import Actor, Articulation, Link


@dataclass
class ContactReadout:
    link_forces: torch.Tensor  # (N, L, 3) net contact force on each monitored robot link
    finger_on_target: torch.Tensor  # (N, 2, 3) force on the left/right finger from the target object
    target_net: torch.Tensor  # (N, 3) net contact force on the target object
    finger_on_handle: torch.Tensor  # (N, 2, 3) force on each finger from the fixture parts carrying handles


class ContactReader:
    """Reads `ContactReadout`s for one robot, its fingers, an optional target object and handle-carrying links."""

    def __init__(
        self,
        scene,
        robot: Articulation,
        link_names: list[str],
        finger_names: tuple[str, str],
        target: Actor | None = None,
        handles: list[Link] | tuple[Link, ...] = (),
    ):
        self.scene, self.robot = scene, robot
        self.link_names = list(link_names)
        self.finger_idx = [self.link_names.index(n) for n in finger_names]
        self.fingers = [robot.links_map[n] for n in finger_names]
        self.target, self.handles = target, list(handles)
        n = scene.num_envs
        self._zeros2 = torch.zeros(n, 2, 3, device=scene.device)
        self._zeros1 = torch.zeros(n, 3, device=scene.device)
        self._ids: tuple[dict[int, int], dict[int, int], int, set[int]] | None = None
        self._relevant: set[int] | None = None

    def read(self) -> ContactReadout:
        if self.scene.gpu_sim_enabled:
            return self._read_gpu()
        return self._read_cpu()

    def _read_gpu(self) -> ContactReadout:
        links = self.robot.get_net_contact_forces(self.link_names)
        on_target, on_handle, target_net = self._zeros2, self._zeros2, self._zeros1
        if self.target is not None:
            on_target = torch.stack([self.scene.get_pairwise_contact_forces(f, self.target) for f in self.fingers], 1)
            target_net = self.target.get_net_contact_forces()
        for handle in self.handles:
            on_handle = on_handle + torch.stack([self.scene.get_pairwise_contact_forces(f, handle) for f in self.fingers], 1)
        return ContactReadout(links, on_target, target_net, on_handle)

    def _entity_ids(self) -> tuple[dict[int, int], dict[int, int], int, set[int]]:
        # Entities are matched by their per-scene id (pybind returns a fresh wrapper for each access); the reader
        # lives as long as its scene, so the ids are looked up once.
        if self._ids is None:
            def eid(obj) -> int:
                return obj._bodies[0].entity.per_scene_id

            self._ids = ({eid(self.robot.links_map[n]): i for i, n in enumerate(self.link_names)},
                         {eid(f): k for k, f in enumerate(self.fingers)},
                         eid(self.target) if self.target is not None else -1,
                         {eid(h) for h in self.handles})
        return self._ids

    def _read_cpu(self) -> ContactReadout:
        link_of, finger_of, target_id, handle_ids = self._entity_ids()
        relevant = self._relevant_ids()
        links = np.zeros((len(self.link_names), 3))
        on_target, on_handle, target_net = np.zeros((2, 3)), np.zeros((2, 3)), np.zeros(3)
        for contact in self.scene.px.get_contacts():
            body0, body1 = contact.bodies
            ids = (body0.entity.per_scene_id, body1.entity.per_scene_id)
            if ids[0] not in relevant and ids[1] not in relevant:  # e.g. a distractor on its support
                continue
            # acts on bodies[0]; -impulse on bodies[1]. A plain sum: np.sum of a short list costs more than its adds
            impulse = sum(p.impulse for p in contact.points)
            for me, other, sign in ((ids[0], ids[1], 1.0), (ids[1], ids[0], -1.0)):
                if me in link_of:
                    links[link_of[me]] += sign * impulse
                if me in finger_of:
                    if other == target_id:
                        on_target[finger_of[me]] += sign * impulse
                    if other in handle_ids:
                        on_handle[finger_of[me]] += sign * impulse
                if me == target_id:
                    target_net += sign * impulse
        dt = self.scene.timestep

        def t(a):
            return torch.as_tensor(a / dt, dtype=torch.float32)[None]

        return ContactReadout(t(links), t(on_target), t(target_net), t(on_handle))

    def _relevant_ids(self) -> set[int]:
        """Every entity a readout sums forces on (the links, the target): contacts between two others are skipped."""
        if self._relevant is None:
            link_of, finger_of, target_id, _ = self._entity_ids()
            self._relevant = set(link_of) | set(finger_of) | ({target_id} if target_id >= 0 else set())
        return self._relevant
