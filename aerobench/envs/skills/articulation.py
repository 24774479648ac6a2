"""Open and Close (arm platform; refrigerator door and counter drawer), spec appendix "Open/Close Outcome Semantics".

S_art = J and R and A and V and N and C and [p = done]:
J goal (q_bar >= 0.75 fridge / 0.90 drawer to open, q_bar <= 0.01 to close), R handle released (the two fingers no
longer both above 0.1 N), A arm within 0.05 rad of its rest pose, V platform below 0.05 m/s and 0.2 rad/s, N no
airframe contact recorded, C minimum sampled clearance of the robot (fingers excluded) to the furniture >= 0.03 m
throughout, and the execution phase p done. The phase is tracked from the signals (`advance_phase`), so any policy
is scored the same way; its failure states are the spec's fail_insert, fail_pinch, fail_slip and fail_drive.
"""

from __future__ import annotations

import math

import torch
from mani_skill.utils.registration import register_env

from ..checks import FailureCause, Phase, consecutive
from ..control.arm import arm_point_positions_body
from ..geometry import body_points_to_world
from ..observations import GRASP_CONFIRM_STEPS, wrap_angle
from ..scenes import articulated
from ..signals import HELD_FORCE_N
from ..tasks import instruction
from .base import AeroSkillEnv
from .evaluator import GoalFeatures, SkillEvaluator

OPEN_THRESHOLD = {"fridge": 0.75, "drawer": 0.90}  # spec: alpha_a
CLOSE_THRESHOLD = 0.01  # spec: q_bar <= 0.01
ARM_REST_TOLERANCE_RAD = 0.05  # spec: arm retraction
STABLE_SPEED_MPS = 0.05  # spec: platform stability
STABLE_ANGULAR_RPS = 0.2
CLEARANCE_M = 0.03  # spec: minimum sampled clearance, fingers excluded
AIRFRAME_CONTACT_N = 0.1  # any recorded airframe contact above this (the finger threshold of the spec) breaks N
AT_HANDLE_M = 0.03  # approach done: tool centre point this close to the handle's grasp point
SLIP_STEPS = 3  # handle contact lost this many steps during the drive: slip
PHASE_LIMIT_STEPS = {"approach": 400, "pinch": 40, "drive": 600}  # 20 s, 2 s, 30 s
CLOSE_START_Q_BAR = (0.85, 1.0)  # Close episodes start this far open
START_CONE_COS = 0.5  # starts lie within 60 deg of the handle's outward normal


def advance_phase(
    phase: torch.Tensor,
    steps: torch.Tensor,
    at_handle: torch.Tensor,
    pinched: torch.Tensor,
    slip_steps: torch.Tensor,
    goal: torch.Tensor,
    released: torch.Tensor,
    retracted: torch.Tensor,
    stable: torch.Tensor,
) -> tuple[torch.Tensor, torch.Tensor]:
    """One control step of the execution phase; returns (phase, control steps spent in it)."""
    P = Phase
    nxt = phase.clone()
    nxt = torch.where((phase == P.APPROACH) & at_handle, P.PINCH, nxt)
    nxt = torch.where((phase == P.APPROACH) & ~at_handle & (steps >= PHASE_LIMIT_STEPS["approach"]), P.FAIL_INSERT, nxt)
    nxt = torch.where((phase == P.PINCH) & pinched, P.DRIVE, nxt)
    nxt = torch.where((phase == P.PINCH) & ~pinched & (steps >= PHASE_LIMIT_STEPS["pinch"]), P.FAIL_PINCH, nxt)
    drive = phase == P.DRIVE
    nxt = torch.where(drive & goal, P.RELEASE, nxt)
    nxt = torch.where(drive & ~goal & (slip_steps >= SLIP_STEPS), P.FAIL_SLIP, nxt)
    nxt = torch.where(drive & ~goal & (slip_steps < SLIP_STEPS) & (steps >= PHASE_LIMIT_STEPS["drive"]), P.FAIL_DRIVE, nxt)
    nxt = torch.where((phase == P.RELEASE) & released, P.RETRACT, nxt)
    nxt = torch.where((phase == P.RETRACT) & retracted & stable, P.DONE, nxt)
    return nxt, torch.where(nxt == phase, steps + 1, torch.zeros_like(steps))


class ArticulationEvaluator(SkillEvaluator):
    """Open or close one fixture per env (`where=("fridge",)`, or both allowed and one sampled per env)."""

    def __init__(self, env, skill: str, where=()):
        super().__init__(env, where)
        self.skill = skill
        self.names = tuple(where) or tuple(n for n in env.setting.fixtures if n in env.built.fixtures)
        self.fixtures = [env.built.fixtures[n] for n in self.names]
        self.fixture_id = self.zeros(torch.long)
        self.phase = self.zeros(torch.long)
        self.phase_steps = self.zeros(torch.long)
        self.slip_steps = self.zeros(torch.long)
        self.pinch_steps = self.zeros(torch.long)  # control steps of a continuous pinch (the tactile confirmation)
        self.contact_seen = self.zeros(torch.bool)
        self.min_clearance = torch.full((self.n,), math.inf, device=self.device)
        rest = env.platform.arm.working_pose_rad if env.platform.arm else ()
        self.arm_rest = torch.tensor(rest, device=self.device)
        self.open_threshold = torch.tensor([OPEN_THRESHOLD[n] for n in self.names], device=self.device)

    def handle_links(self) -> list:
        return [f.links_map[articulated.MOVING_LINK[n]] for n, f in zip(self.names, self.fixtures)]

    def _per_env(self, values: list[torch.Tensor]) -> torch.Tensor:
        stacked = torch.stack(values, dim=0)  # (F, N, ...)
        index = self.fixture_id.view(1, -1, *([1] * (stacked.dim() - 2))).expand(1, *stacked.shape[1:])
        return torch.gather(stacked, 0, index)[0]

    def progress(self) -> torch.Tensor:
        """Normalized articulation progress q_bar `(N,)` of each env's fixture."""
        return self._per_env([articulated.normalized_progress(f) for f in self.fixtures])

    def handle_normal(self) -> torch.Tensor:
        """Outward normal `(N, 3)` of each env's door or drawer front at the handle."""
        return self._per_env([articulated.front_normal(n, f) for n, f in zip(self.names, self.fixtures)])

    def handle_point(self) -> torch.Tensor:
        return self._per_env([articulated.handle_grasp_point(n, f) for n, f in zip(self.names, self.fixtures)])

    def start_cone(self, env_idx: torch.Tensor) -> tuple[torch.Tensor, float]:
        """Where an episode that begins at this fixture starts: in front of the handle, within 60 deg of its outward
        normal (`sample_start`'s `within_cone`). 0.5-1 m from the handle without it, a chain start could lie
        beside the fridge or behind the wall it stands against, a 15 m flight round the house from the door."""
        return self.handle_normal()[env_idx], START_CONE_COS

    def sample(self, env_idx: torch.Tensor, opens_later: bool = False) -> torch.Tensor:
        """Pick each env's fixture and its starting state: closed to open it, open (q_bar 0.85-1) to close it."""
        m = len(env_idx)
        self.fixture_id[env_idx] = self.env.episode_rng.randint(len(self.names), env_idx)
        if self.skill == "close" and not opens_later:
            lo, hi = CLOSE_START_Q_BAR
            q_bar = lo + self.env.episode_rng.rand(env_idx) * (hi - lo)
            for k, fixture in enumerate(self.fixtures):
                rows = env_idx[self.fixture_id[env_idx] == k]
                if len(rows):
                    articulated.set_progress(fixture, rows, q_bar[self.fixture_id[env_idx] == k])
        return torch.ones(m, dtype=torch.bool, device=self.device)

    def begin(self, env_idx):
        self.phase[env_idx] = int(Phase.APPROACH)
        self.phase_steps[env_idx] = 0
        self.slip_steps[env_idx] = 0
        self.pinch_steps[env_idx] = 0
        self.contact_seen[env_idx] = False
        self.min_clearance[env_idx] = math.inf

    def anchor(self, env_idx):
        return self.handle_point()[env_idx]

    def _robot_clearance(self, ctx) -> torch.Tensor:
        env = self.env
        pts = body_points_to_world(env.proxy_points, ctx.state.position, ctx.state.rotation)
        if env.platform.arm is not None:
            arm = arm_point_positions_body(env.agent.arm_qpos(), env.platform.arm)
            body = torch.stack([arm["shoulder"], arm["elbow"], arm["wrist"], 0.5 * (arm["shoulder"] + arm["elbow"])], 1)
            arm_world = ctx.state.position[:, None] + torch.einsum("nij,npj->npi", ctx.state.rotation, body)
            pts = torch.cat([pts, arm_world], dim=1)
        return env.robot_clearance(pts)

    def update(self, ctx, mine):
        q_bar = self.progress()
        if self.skill == "open":
            goal = q_bar >= self.open_threshold[self.fixture_id]
        else:
            goal = q_bar <= CLOSE_THRESHOLD
        forces = torch.linalg.norm(ctx.readout.finger_on_handle, dim=-1)
        pinched = (forces > HELD_FORCE_N).all(-1)
        released = ~pinched
        arm_q = self.env.agent.arm_qpos()
        retracted = (arm_q - self.arm_rest).abs().max(-1).values < ARM_REST_TOLERANCE_RAD if arm_q.shape[-1] else torch.ones_like(goal)
        stable = (ctx.speed < STABLE_SPEED_MPS) & (ctx.angular_speed < STABLE_ANGULAR_RPS)
        at_handle = torch.linalg.norm(ctx.tcp - self.handle_point(), dim=-1) < AT_HANDLE_M
        self.contact_seen = self.keep(mine, self.contact_seen | (ctx.airframe_force > AIRFRAME_CONTACT_N), self.contact_seen)
        self.min_clearance = self.keep(mine, torch.minimum(self.min_clearance, self._robot_clearance(ctx)), self.min_clearance)
        self.slip_steps = self.keep(mine, consecutive(self.slip_steps, ~pinched), self.slip_steps)
        self.pinch_steps = self.keep(mine, consecutive(self.pinch_steps, pinched), self.pinch_steps)
        phase, steps = advance_phase(
            self.phase, self.phase_steps, at_handle, pinched, self.slip_steps, goal, released, retracted, stable
        )
        self.phase, self.phase_steps = self.keep(mine, phase, self.phase), self.keep(mine, steps, self.phase_steps)
        no_contact = ~self.contact_seen
        clear = self.min_clearance >= CLEARANCE_M
        success = goal & released & retracted & stable & no_contact & clear & (self.phase == Phase.DONE)
        flags = [
            (FailureCause.AIRFRAME_CONTACT, ~no_contact),
            (FailureCause.CLEARANCE, ~clear),
            (FailureCause.PHASE, self.phase >= Phase.FAIL_INSERT),
        ]
        signals = {
            "articulation_progress": q_bar,
            "is_goal_reached": goal,
            "is_handle_pinched": pinched,
            "is_released_handle": released,
            "is_arm_retracted": retracted,
            "is_platform_stable": stable,
            "no_airframe_contact": no_contact,
            "min_clearance": self.min_clearance.clone(),
            "phase": self.phase.clone(),
            "tcp_to_handle": torch.linalg.norm(ctx.tcp - self.handle_point(), dim=-1),
        }
        return signals, success, flags

    def goal_features(self, ctx) -> GoalFeatures:
        normal = self.handle_normal()
        facing = torch.atan2(-normal[:, 1], -normal[:, 0])
        return GoalFeatures(
            goal_point=self.handle_point(),
            origin=ctx.tcp,
            heading_error=wrap_angle(facing - ctx.state.yaw),
            progress=self.progress(),
            # the fingers' pinch on the handle, confirmed as an object's grasp is (task state version 5): without it a
            # policy cannot tell the moment it has the handle (the drive begins) from the insert before it
            grasp_confirmed=self.pinch_steps >= GRASP_CONFIRM_STEPS,
        )

    def instruction(self, env):
        return instruction(self.skill, target=self.names[int(self.fixture_id[env])])

    def privileged_obs(self):
        return {f"{self.skill}_handle": self.handle_point(), f"{self.skill}_progress": self.progress()[:, None]}


class _ArticulationEnv(AeroSkillEnv):
    uses_object = False

    def __init__(self, *args, fixture: str | None = None, **kwargs):
        self.fixture_name = fixture
        super().__init__(*args, **kwargs)

    def _check_setting(self) -> None:
        super()._check_setting()
        if self.fixture_name is not None and self.fixture_name not in self.setting.fixtures:
            raise ValueError(
                f"fixture {self.fixture_name!r} is not part of {self.setting.name}; its fixtures are: "
                f"{', '.join(self.setting.fixtures)}"
            )

    def _make_evaluators(self):
        where = (self.fixture_name,) if self.fixture_name else ()
        return [ArticulationEvaluator(self, self.skill, where)]

    def _handle_links(self):
        return self.evaluators[0].handle_links()

    def _sample_episode(self, env_idx):
        ev = self.evaluators[0]
        ok = ev.sample(env_idx)
        cone = ev.start_cone(env_idx)
        normal = cone[0]
        # in front of the handle, already facing the door: the arm reaches straight at it
        position, yaw, free = self.sample_start(
            env_idx, ev.anchor(env_idx), torch.full((len(env_idx),), -1e9, device=self.device),
            heading=torch.atan2(-normal[:, 1], -normal[:, 0]), within_cone=cone,
        )
        self.set_drone(env_idx, position, yaw)
        ev.begin(env_idx)
        for i in env_idx.tolist():
            self.instructions[i] = ev.instruction(i)
        return ok & free


@register_env("AeroOpen-v1", max_episode_steps=1200)
class AeroOpenEnv(_ArticulationEnv):
    """**Task description.** With the arm platform, pinch the handle of the refrigerator door (a 50 mm vertical bar,
    fingers closing horizontally at zero wrist roll) or the counter drawer (24 mm tall handle, wrist rolled 90 deg),
    pull it open, release, retract the arm and hover still. Args: `setting`, `fixture` (fridge | drawer; default
    sampled per env).

    **Randomizations.** Layout, materials, lights, which fixture, and the start 0.5-1 m from the handle, facing it.

    **Success conditions.** S_art (module docstring) with q_bar >= 0.75 (fridge) or 0.90 (drawer).
    **Fails** on airframe contact, clearance below 0.03 m, a failed phase, or the flight envelope.
    """

    skill = "open"


@register_env("AeroClose-v1", max_episode_steps=1200)
class AeroCloseEnv(_ArticulationEnv):
    """**Task description.** As AeroOpen-v1, but the fixture starts 85-100% open and must end at q_bar <= 0.01.

    **Randomizations.** As AeroOpen-v1, plus the starting opening.

    **Success conditions.** S_art with q_bar <= 0.01. **Fails** as AeroOpen-v1.
    """

    skill = "close"
