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

    # the CPU readout's rows after the links': each finger's force from the target, the target's net force, each
    # finger's force from the handle parts
    ON_TARGET, TARGET_NET, ON_HANDLE, EXTRA_ROWS = 0, 2, 3, 5

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
        self._bodies: tuple[dict, dict, object, set] | None = None
        self._routes: dict[tuple, int] = {}  # body pair -> index in _route_rows
        self._route_rows: list[tuple[tuple[int, float], ...]] = [()]
        self._routing_matrix = np.zeros((len(self.link_names) + self.EXTRA_ROWS, 0))  # `_routing()`
        self._dt = scene.timestep  # the physics step: impulses over it are forces

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

    def _route(self, body0, body1) -> int:
        """The index in `self._route_rows` of what a contact between `body0` and `body1` adds its impulse to: readout
        rows (links, then the fingers' force from the target, the target's net force, the fingers' force from the
        handles) with the sign it adds them with, as it acts on `body0` and with minus itself on `body1`. Index 0 is
        no row: a pair the readout does not follow (e.g. a distractor on its support)."""
        link_of, finger_of, target, handles = self._body_index()
        n_links = len(self.link_names)
        rows: list[tuple[int, float]] = []
        for me, other, sign in ((body0, body1, 1.0), (body1, body0, -1.0)):
            if me in link_of:
                rows.append((link_of[me], sign))
            if me in finger_of:
                if target is not None and other is target:
                    rows.append((n_links + self.ON_TARGET + finger_of[me], sign))
                if other in handles:
                    rows.append((n_links + self.ON_HANDLE + finger_of[me], sign))
            if target is not None and me is target:
                rows.append((n_links + self.TARGET_NET, sign))
        route = tuple(rows)
        if not route:
            return 0
        if route not in self._route_rows:
            self._route_rows.append(route)
        return self._route_rows.index(route)

    def _routing(self) -> np.ndarray:
        """`(rows, routes)`: the sign each route's impulse adds to each readout row (all routes found so far)."""
        matrix = self._routing_matrix
        if matrix.shape[1] != len(self._route_rows):
            matrix = np.zeros((len(self.link_names) + self.EXTRA_ROWS, len(self._route_rows)))
            for k, route in enumerate(self._route_rows):
                for row, sign in route:
                    matrix[row, k] += sign
            self._routing_matrix = matrix
        return matrix

    def _body_index(self) -> tuple[dict, dict, object, set]:
        # PhysX bodies by their Python wrapper: pybind returns the one wrapper of a live C++ object, and ManiSkill
        # holds each body's, so a contact's `bodies` are these very objects and an identity lookup finds them (a
        # lookup through `body.entity.per_scene_id` costs two more wrappers per body). Found once per scene.
        if self._bodies is None:
            def body(obj):
                return obj._bodies[0]

            link_of = {body(self.robot.links_map[n]): i for i, n in enumerate(self.link_names)}
            finger_of = {body(f): k for k, f in enumerate(self.fingers)}
            target = body(self.target) if self.target is not None else None
            self._bodies = (link_of, finger_of, target, {body(h) for h in self.handles})
        return self._bodies

    def _read_cpu(self) -> ContactReadout:
        # Python touches each point of a followed contact once (its impulse, a 3-vector). The points are gathered per
        # route (pairs that feed the same rows with the same signs: e.g. every shape of a resting object against its
        # support) and each route's sum is one numpy call; one product spreads them over the readout's rows. The
        # route of a body pair is found once and kept.
        routes = self._routes
        gathered: dict[int, list[np.ndarray]] = {}
        for contact in self.scene.px.get_contacts():
            pair = tuple(contact.bodies)
            route = routes.get(pair)
            if route is None:
                route = routes[pair] = self._route(*pair)
            if route:
                points = gathered.get(route)
                if points is None:
                    points = gathered[route] = []
                points.extend([p.impulse for p in contact.points])
        totals = np.zeros((len(self._route_rows), 3))
        for route, points in gathered.items():
            if points:
                totals[route] = np.concatenate(points).reshape(-1, 3).sum(axis=0, dtype=np.float64)
        # the rows are cut on the numpy side and each handed to torch as is: half the cost of torch's own slicing
        forces = (self._routing() @ totals / self._dt).astype(np.float32)[None]
        n = len(self.link_names)
        on_target, on_handle = n + self.ON_TARGET, n + self.ON_HANDLE
        fields = (forces[:, :n], forces[:, on_target : on_target + 2], forces[:, n + self.TARGET_NET],
                  forces[:, on_handle : on_handle + 2])
        return ContactReadout(*map(torch.from_numpy, fields))
