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
        self._body_index: tuple[dict, dict, object, set, set] | None = None

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

    def _bodies(self) -> tuple[dict, dict, object, set, set]:
        # PhysX bodies by their Python wrapper: pybind returns the one wrapper of a live C++ object, and ManiSkill
        # holds each body's, so a contact's `bodies` are these very objects and an identity lookup finds them (a
        # lookup through `body.entity.per_scene_id` costs two more wrappers per body). Found once per scene.
        if self._body_index is None:
            def body(obj):
                return obj._bodies[0]

            link_of = {body(self.robot.links_map[n]): i for i, n in enumerate(self.link_names)}
            finger_of = {body(f): k for k, f in enumerate(self.fingers)}
            target = body(self.target) if self.target is not None else None
            handles = {body(h) for h in self.handles}
            # every body a readout sums forces on (the links, the target): contacts between two others are skipped
            relevant = set(link_of) | set(finger_of) | ({target} if target is not None else set())
            self._body_index = (link_of, finger_of, target, handles, relevant)
        return self._body_index

    def _read_cpu(self) -> ContactReadout:
        link_of, finger_of, target, handles, relevant = self._bodies()
        links = np.zeros((len(self.link_names), 3))
        on_target, on_handle, target_net = np.zeros((2, 3)), np.zeros((2, 3)), np.zeros(3)
        for contact in self.scene.px.get_contacts():
            body0, body1 = contact.bodies
            if body0 not in relevant and body1 not in relevant:  # e.g. a distractor on its support
                continue
            # acts on bodies[0]; -impulse on bodies[1]. A plain sum: np.sum of a short list costs more than its adds
            impulse = sum(p.impulse for p in contact.points)
            for me, other, sign in ((body0, body1, 1.0), (body1, body0, -1.0)):
                if me in link_of:
                    links[link_of[me]] += sign * impulse
                if me in finger_of:
                    if other is target:
                        on_target[finger_of[me]] += sign * impulse
                    if other in handles:
                        on_handle[finger_of[me]] += sign * impulse
                if me is target:
                    target_net += sign * impulse
        dt = self.scene.timestep

        def t(a):
            return torch.as_tensor(a / dt, dtype=torch.float32)[None]

        return ContactReadout(t(links), t(on_target), t(target_net), t(on_handle))
