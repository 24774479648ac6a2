"""What every skill expert shares: per-env phase bookkeeping and assembling the normalized action.

An expert reads privileged simulator state from the env (object poses, goals, the layout) and returns the same
normalized action a learned policy would, so its demonstrations are ordinary trajectories. Every step is batched
over envs: phases are `(N,)` tensors and transitions are `torch.where`, never a Python loop over envs.
"""

from __future__ import annotations

import torch

from ..envs.control.arm import ELBOW, ArmParams, elbow_gravity_torque
from ..envs.control.virtual_joints import AirframeState
from ..envs.platforms import CONTROL_HZ, MAX_YAW_RATE_RPS
from ..envs.skills.place import carried_arm_pose
from .motion import POSITION_GAIN, YAW_GAIN, flight_action, velocity_towards, wrap_angle, yaw_rate_towards

ARM_YAW_GAIN = 0.6  # 1/s
ARM_MAX_YAW_RATE = 0.4  # rad/s
# A held heavy object droops a level forearm (its static elbow torque exceeds the elbow's 0.9 N m); the elbow then sits
# at its torque limit with nothing left to damp with, and the object swings on it with the airframe's accelerations
# (m a r: 0.37 kg x 2 m/s^2 x 0.24 m = 0.18 N m). Carried, the forearm is turned down until the static torque is at
# most this share of the limit (about 1.05-1.1 rad below level for the 0.37-0.41 kg cans), so the servo has the rest
# for the swing: at 85% (0.2 rad below where it hung) the elbow swung between 0.07 and 0.97 rad below level in flight.
HELD_ELBOW_TORQUE_SHARE = 0.6
HELD_DROOP_STEP_RAD = 0.05
HELD_DROOP_MAX_RAD = 1.5

class SkillExpert:
    """Base of the per-skill experts. `evaluator` is the env's evaluator of the skill being demonstrated."""

    def __init__(self, env, evaluator):
        self.env = env
        self.evaluator = evaluator
        self.n = env.num_envs
        self.device = env.device
        self.phase = torch.zeros(self.n, dtype=torch.long, device=self.device)
        self.timer = torch.zeros(self.n, dtype=torch.long, device=self.device)
        self.platform = env.platform
        self.has_arm = env.platform.arm is not None
        arm = env.platform.arm
        rest = arm.working_pose_rad if self.has_arm else ()
        self.arm_rest = torch.tensor(rest, dtype=torch.float32, device=self.device)
        self.arm_top_down = torch.tensor(arm.top_down_pose_rad if self.has_arm else (), dtype=torch.float32, device=self.device)
        self.arm_carry = torch.tensor(arm.carry_pose_rad if self.has_arm else (), dtype=torch.float32, device=self.device)
        self.arm_params = ArmParams.from_spec(arm, env.platform.gripper, self.device) if self.has_arm else None
        # The arm platform's yaw torque is limited to 0.12 N m, so its heading lags the commanded yaw rate: a gentler
        # heading loop keeps it from ringing (the gripper platform turns fast enough for the default).
        self.yaw_gain, self.max_yaw_rate = (ARM_YAW_GAIN, ARM_MAX_YAW_RATE) if self.has_arm else (YAW_GAIN, MAX_YAW_RATE_RPS)
        self.velocity_command = torch.zeros(self.n, 3, device=self.device)  # the last commanded velocity (m/s)
        self._no_droop = torch.zeros(self.n, dtype=torch.bool, device=self.device)  # the gripper platform's, every step

    def reset(self, env_idx: torch.Tensor) -> None:
        self.phase[env_idx] = 0
        self.timer[env_idx] = 0

    def held_depth(self, env_idx: torch.Tensor) -> torch.Tensor:
        """`(len(env_idx),)` how far the held object's bottom hangs below the tool centre point (m), for the route
        planner's clearance: measured, since where the object sits in the fingers depends on the grasp (the
        arm's top-down grasp holds a tall box up to 6 cm higher on it than its nominal grasp point); never less than
        the nominal grasp height."""
        nominal = self.env.target_grasp_point[env_idx, 2]
        measured = (self.tcp() - self.object_position())[env_idx, 2]
        return torch.maximum(nominal, measured)

    def reaches_in(self, pick) -> torch.Tensor:
        """`(N,)` envs where the arm platform picks with `pick` (a pick evaluator) from the side, reaching into an
        enclosure (a fridge shelf) with the forearm level; everywhere else the arm picks top down, as the gripper does."""
        return pick.enclosed & self.has_arm

    def pick_arm_pose(self, pick) -> torch.Tensor:
        """`(N, 3)` arm joint targets while picking with `pick`: the working pose reaching in, else the top-down pose."""
        return torch.where(self.reaches_in(pick)[:, None], self.arm_rest, self.arm_top_down)

    def carry_arm_pose(self, pick) -> torch.Tensor:
        """`(N, 3)` arm joint targets while carrying what `pick` grasped (None: the working pose, e.g. a Place start):
        folded under the airframe (`carry_pose_rad`) after a reach-in, else the top-down pose it was picked in. Both
        keep the forearm's angle, so the object stays upright."""
        return carried_arm_pose(self.platform.arm, None if pick is None else pick.enclosed, self.n, self.device)

    def forearm_droops(self, pick) -> torch.Tensor:
        """`(N,)` envs where the object `pick` grasps is too heavy for the forearm in the pose it is picked in: the
        elbow's static torque with the object at the grasp point exceeds its limit (a reach-in's level forearm holds
        0.28 kg; the 0.37-0.41 kg cans droop it 0.6-0.9 rad as they come off the shelf)."""
        if not self.has_arm:
            return self._no_droop
        torque = elbow_gravity_torque(self.pick_arm_pose(pick), self.arm_params, self.env.target_mass)
        return torque > self.arm_params.torque_limit[ELBOW]

    def held_arm_pose(self, pose: torch.Tensor) -> torch.Tensor:
        """`(N, 3)` the arm pose to carry the target object in: `pose`, except where its static elbow torque with the
        object at the grasp point exceeds the elbow's limit (a heavy can on a level forearm); there the elbow is turned
        down from `pose` by the first multiple of `HELD_DROOP_STEP_RAD` whose static torque is at most
        `HELD_ELBOW_TORQUE_SHARE` of the limit."""
        steps = torch.arange(0.0, HELD_DROOP_MAX_RAD + 1e-6, HELD_DROOP_STEP_RAD, device=self.device)  # (K,)
        candidates = pose[None].repeat(len(steps), 1, 1)
        candidates[..., ELBOW] += steps[:, None]
        load = self.env.target_mass.expand(self.n).repeat(len(steps))
        torque = elbow_gravity_torque(candidates.reshape(-1, 3), self.arm_params, load).reshape(len(steps), self.n)
        within = torque <= HELD_ELBOW_TORQUE_SHARE * self.arm_params.torque_limit[ELBOW]
        first = torch.where(within.any(0), within.float().argmax(0), torch.full_like(within[0], len(steps) - 1, dtype=torch.long))
        held = pose.clone()
        held[:, ELBOW] = pose[:, ELBOW] + steps[first]
        return torch.where((torque[0] > self.arm_params.torque_limit[ELBOW])[:, None], held, pose)

    def act(self) -> torch.Tensor:
        raise NotImplementedError

    # ----------------------------------------------------------------------------------------------------------------
    def state(self) -> AirframeState:
        return self.env.current_step_context().state  # computed once per control step by the env

    def tcp(self) -> torch.Tensor:
        return self.env.current_step_context().tcp

    def object_position(self) -> torch.Tensor:
        """The target object's pose origin (its bottom centre) `(N, 3)` at this control step."""
        return self.env.current_step_context().object_pose.p

    def goto(self, phase: torch.Tensor, condition: torch.Tensor, new_phase: int) -> torch.Tensor:
        """Move envs in `phase` where `condition` holds to `new_phase` (timer restarts)."""
        self.phase, self.timer, move = goto_phase(self.phase, self.timer, phase, condition, new_phase)
        return move

    def in_phase(self, value: int) -> torch.Tensor:
        return self.phase == value

    def advance_timer(self) -> None:
        self.timer = self.timer + 1

    def action(
        self,
        tcp_target: torch.Tensor,
        max_speed: torch.Tensor,
        yaw_target: torch.Tensor,
        gripper: torch.Tensor,
        arm_target: torch.Tensor | None = None,
        gain: torch.Tensor | float = POSITION_GAIN,
        tracked: torch.Tensor | None = None,
        yaw_rate_feedforward: torch.Tensor | None = None,
        yaw_gain: torch.Tensor | None = None,
        velocity_override: tuple[torch.Tensor, torch.Tensor] | None = None,
        max_accel: float | None = None,
    ) -> torch.Tensor:
        """Track `tcp_target` `(N, 3)` under `max_speed` `(N,)` with position `gain` (1/s, scalar or `(N,)`), turn to
        `yaw_target`, set the gripper (-1 closed) and the arm joint targets (default: the rest pose).
        `tracked` `(N, 3)` replaces the tool centre point as the point driven to the target (e.g. the airframe).
        `max_accel` (m/s^2) bounds how fast the velocity command may change from the last one (a ramp, not a step)."""
        state = self.state()
        point = self.tcp() if tracked is None else tracked
        velocity = tracking_velocity(point, tcp_target, max_speed, gain, velocity_override)
        if max_accel is not None:
            change = velocity - self.velocity_command
            norm = torch.linalg.norm(change, dim=-1, keepdim=True)
            velocity = self.velocity_command + change * torch.clamp((max_accel / CONTROL_HZ) / (norm + 1e-9), max=1.0)
        self.velocity_command = velocity
        if yaw_gain is None:
            yaw_rate = yaw_rate_towards(state.yaw, yaw_target, self.max_yaw_rate, self.yaw_gain)
        else:  # per-env gains (e.g. stiffer while a door holds the heading)
            yaw_rate = torch.clamp(yaw_gain * wrap_angle(yaw_target - state.yaw), -MAX_YAW_RATE_RPS, MAX_YAW_RATE_RPS)
        if yaw_rate_feedforward is not None:  # e.g. following a door that turns under the gripper
            yaw_rate = torch.clamp(yaw_rate + yaw_rate_feedforward, -MAX_YAW_RATE_RPS, MAX_YAW_RATE_RPS)
        arm_action = None
        if self.has_arm:
            target = self.arm_rest.expand(self.n, 3) if arm_target is None else arm_target
            arm_action = self.env.agent.body_controller.arm_action(target)
        return expert_action(velocity, yaw_rate, gripper, arm_action)


def goto_phase(phase: torch.Tensor, timer: torch.Tensor, current: int, condition: torch.Tensor, new: int
               ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Move envs in phase `current` where `condition` holds to `new`, their timer restarted: the new phase and timer,
    and who moved."""
    move = condition & (current == phase)
    return torch.where(move, torch.full_like(phase, new), phase), torch.where(move, torch.zeros_like(timer), timer), move


def tracking_velocity(point: torch.Tensor, target: torch.Tensor, max_speed: torch.Tensor, gain: torch.Tensor | float,
                      override: tuple[torch.Tensor, torch.Tensor] | None = None) -> torch.Tensor:
    """The velocity `(N, 3)` that drives `point` to `target` with position `gain` (1/s, scalar or `(N,)`) under
    `max_speed`; `override` (mask (N,), velocity (N, 3)) is commanded directly where masked."""
    gain = torch.as_tensor(gain, dtype=torch.float32, device=point.device)
    velocity = velocity_towards((target - point) * (gain[:, None] if gain.dim() else gain), max_speed, gain=1.0)
    if override is not None:
        mask, direct = override
        velocity = torch.where(mask[:, None], direct, velocity)
    return velocity


def expert_action(velocity: torch.Tensor, yaw_rate: torch.Tensor, gripper: torch.Tensor,
                  arm_action: torch.Tensor | None = None) -> torch.Tensor:
    """The normalized action `(N, 5)` (`(N, 8)` with the arm) of a commanded velocity (m/s), yaw rate (rad/s),
    gripper (-1 closed) and normalized arm action."""
    parts = [flight_action(velocity, yaw_rate)] + ([arm_action] if arm_action is not None else []) + [gripper[:, None]]
    return torch.cat(parts, dim=-1)

