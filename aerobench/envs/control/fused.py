"""One physics step of the airframe as a single fused kernel: joints in, joint efforts and telemetry out.

`physics_step` chains the laws of `virtual_joints`, `flight` and `arm` (each stays a readable function, one per spec
equation) with no Python branch on a tensor value and no tensor-to-Python conversion, so the same code is a
CUDA-graph capturable step on physx_cuda and one compiled kernel on a CPU. With one env on a CPU the eager step is
about 60 small torch ops whose dispatch, not arithmetic, is the cost; `fused_physics_step` returns the process's one
step per platform (shared, so it compiles once per process).

The step runs as `kernels.Kernel`s: on a CPU compiled ahead of time (AOTInductor; on the 2-core machine a call
costs about 10 instead of 210 microseconds through dynamo), cached on disk and keyed by the source of the control
laws and the platform; elsewhere `torch.compile`; the eager function where compilation fails (reported once).
`AEROBENCH_COMPILE=0` forces the eager path; `AEROBENCH_COMPILE_MODE=reduce-overhead` asks inductor to capture the
step in a CUDA graph on physx_cuda (docs/gpu.md).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import partial
from pathlib import Path
from typing import NamedTuple

import torch

from ...accel import Kernel, all_contiguous, compile_requested
from ..platforms import PlatformSpec
from .arm import ArmParams, arm_servo_torques, arm_weight_feedforward_body
from .flight import FlightMemory, FlightOutput, FlightParams, flight_laws
from .payload import ControllerMode, update_payload_estimate
from .virtual_joints import NUM_VIRTUAL_JOINTS, AirframeState, airframe_state_from_joints, joint_efforts_from_wrench


class StepResult(NamedTuple):
    """What one fused step returns, as plain `(N, ...)` tensors."""

    efforts: torch.Tensor  # (N, 6 [+ arm joints]) efforts of the controller's joints, in their order
    xi: torch.Tensor  # the controller memory's new integral and desired heading
    yaw_des: torch.Tensor
    rotation: torch.Tensor  # the airframe state it read (position and velocity are slices of q and qd: an output
    angular_velocity_body: torch.Tensor  # that aliases an input costs a compiled graph a slow path at every call)
    rotor_thrusts: torch.Tensor  # FlightOutput's fields
    force_world: torch.Tensor
    torque_world: torch.Tensor
    force_des: torch.Tensor
    rotation_des: torch.Tensor
    thrust: torch.Tensor
    torque_body_cmd: torch.Tensor
    velocity_error: torch.Tensor

    def state(self, q: torch.Tensor, qd: torch.Tensor) -> AirframeState:
        """The airframe state, given the joint positions and velocities the step read."""
        return AirframeState(q[:, :3], qd[:, :3], self.rotation, self.angular_velocity_body)

    def output(self) -> FlightOutput:
        return FlightOutput(*self[5:])


def physics_step(
    q: torch.Tensor,
    qd: torch.Tensor,
    velocity_cmd: torch.Tensor,
    yaw_rate_cmd: torch.Tensor,
    xi: torch.Tensor,
    yaw_des: torch.Tensor,
    mass_hat: torch.Tensor,
    k_R: torch.Tensor,
    k_w: torch.Tensor,
    needs_yaw_sync: torch.Tensor,
    params: FlightParams,
    arm: ArmParams | None = None,
    arm_target: torch.Tensor | None = None,
    contact_mode: torch.Tensor | None = None,
) -> StepResult:
    """Controller joint positions/velocities `(N, 6 [+3])` -> their efforts and the controller's new memory.

    Envs flagged in `needs_yaw_sync` (just reset) take their current heading as the desired one, without a branch.
    """
    q_v, qd_v = q[:, :NUM_VIRTUAL_JOINTS], qd[:, :NUM_VIRTUAL_JOINTS]
    state = airframe_state_from_joints(q_v, qd_v)
    yaw_des = torch.where(needs_yaw_sync, state.yaw, yaw_des)
    feedforward = arm_torques = None
    if arm is not None:
        q_arm, qd_arm = q[:, NUM_VIRTUAL_JOINTS:], qd[:, NUM_VIRTUAL_JOINTS:]
        payload = (mass_hat - params.mass).clamp_min(0.0)  # the carried object's estimated mass (payload-aware)
        feedforward = arm_weight_feedforward_body(state.rotation, q_arm, arm, params.gravity, payload)
        feedforward = torch.where(contact_mode[:, None], torch.zeros_like(feedforward), feedforward)
        arm_torques = arm_servo_torques(q_arm, qd_arm, arm_target, arm, contact_mode)
    out, xi, yaw_des = flight_laws(state, velocity_cmd, yaw_rate_cmd, xi, yaw_des, mass_hat, k_R, k_w, params, feedforward)
    efforts = joint_efforts_from_wrench(q_v, out.force_world, out.torque_world)
    if arm_torques is not None:
        efforts = torch.cat([efforts, arm_torques], dim=-1)
    return StepResult(efforts, xi, yaw_des, state.rotation, state.angular_velocity_body,
                      out.rotor_thrusts, out.force_world, out.torque_world, out.force_des, out.rotation_des, out.thrust,
                      out.torque_body_cmd, out.velocity_error)


def physics_step_efforts(
    q_all: torch.Tensor,
    qd_all: torch.Tensor,
    velocity_cmd: torch.Tensor,
    yaw_rate_cmd: torch.Tensor,
    xi: torch.Tensor,
    yaw_des: torch.Tensor,
    mass_hat: torch.Tensor,
    k_R: torch.Tensor,
    k_w: torch.Tensor,
    needs_yaw_sync: torch.Tensor,
    params: FlightParams,
    arm: ArmParams | None = None,
    arm_target: torch.Tensor | None = None,
    contact_mode: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """`physics_step` as the body controller runs it every physics step: the whole articulation's joint positions
    and velocities `(N, J)` in (the controller's joints lead, the PhysX-driven finger joints follow), the effort of
    every joint `(N, J)` (zero on the fingers), the new integral and desired heading out. Only what the next step
    needs leaves the kernel (each output of a compiled call costs about a microsecond); `physics_step` gives the rest."""
    n = NUM_VIRTUAL_JOINTS + (arm_target.shape[1] if arm is not None else 0)
    result = physics_step(q_all[:, :n], qd_all[:, :n], velocity_cmd, yaw_rate_cmd, xi, yaw_des, mass_hat, k_R, k_w,
                          needs_yaw_sync, params, arm, arm_target, contact_mode)
    efforts = torch.cat([result.efforts, torch.zeros_like(q_all[:, n:])], dim=-1)
    return efforts, result.xi, result.yaw_des


# the memory fields the payload-aware switches compute (`supported` is the step's `is_set_down` itself: an output
# that aliases an input is left out of a compiled call)
PAYLOAD_FIELDS = ("xi", "mass_hat", "k_R", "k_w", "grasp_steps", "payload_active")


def payload_update_flat(xi, yaw_des, mass_hat, k_R, k_w, grasp_steps, payload_active, supported, is_grasped,
                        is_set_down, object_mass, params: FlightParams) -> tuple[torch.Tensor, ...]:
    """`update_payload_estimate` (payload-aware) of flat tensors: the `PAYLOAD_FIELDS` of the new memory."""
    memory = FlightMemory(xi, yaw_des, mass_hat, k_R, k_w, grasp_steps, payload_active, supported)
    new = update_payload_estimate(memory, params, is_grasped, is_set_down, object_mass, ControllerMode.PAYLOAD_AWARE)
    return tuple(getattr(new, name) for name in PAYLOAD_FIELDS)


def _control_sources() -> list[Path]:
    """Every module the step chains (this package and the platform constants)."""
    here = Path(__file__).resolve().parent
    return sorted(here.glob("*.py")) + [here.parent / "platforms.py"]


class FusedPhysicsStep:
    """`physics_step` for one platform, its parameters bound: call with the tensors only (the arm platform adds
    `arm_target` and `contact_mode`) for the full `StepResult`, or `efforts(...)` with the whole articulation's joints
    for what the body controller needs every physics step (`physics_step_efforts`). Each is a `kernels.Kernel`:
    compiled on its first call (ahead of time on a CPU, else `torch.compile`), on any compiler failure the next
    option, reported once. `backend` says which ran last: "compiled ahead of time", "compiled", "eager" (asked for)
    or "eager (fallback: <reason>)".
    """

    def __init__(self, platform: PlatformSpec, device: torch.device | str, compile: bool):
        self.platform = platform
        self.params = FlightParams.from_platform(platform, device)
        self.arm = ArmParams.from_spec(platform.arm, platform.gripper, device) if platform.arm else None
        sources = _control_sources()

        def kernel(variant: str, fn: Callable, **options) -> Kernel:
            # the shapes follow from q's (N and the joint count): one comparison per call finds the loaded package
            return Kernel(fn, "physics_step", (variant, repr(platform)), sources, device, compile,
                          shape_key=lambda tensors: tensors[0].shape, **options)

        # the 240 Hz loop's step keeps its intermediates on the stack (one output, many intermediates: 2x cheaper a
        # call than on the heap) and its kernel is called directly (without the package's runner: 5 instead of
        # 14 us a call right after a physics step, docs/performance.md)
        self.kernels = {"full": kernel("full", self.eager), "efforts": kernel("efforts", self.eager_efforts),
                        "efforts_in_place": kernel("efforts_in_place", self.eager_efforts_in_place,
                                                   stack_allocation=True, direct=True),
                        "airframe_state": kernel("airframe_state", self.eager_airframe_state),
                        "payload": kernel("payload", partial(payload_update_flat, params=self.params))}
        self._last = self.kernels["full"]
        self.cuda_graphs = self._last.cuda_graphs

    @property
    def backend(self) -> str:
        return self._last.backend

    def eager(self, q, qd, velocity_cmd, yaw_rate_cmd, xi, yaw_des, mass_hat, k_R, k_w, needs_yaw_sync,
              arm_target=None, contact_mode=None) -> StepResult:
        return physics_step(q, qd, velocity_cmd, yaw_rate_cmd, xi, yaw_des, mass_hat, k_R, k_w, needs_yaw_sync,
                            self.params, self.arm, arm_target, contact_mode)

    def eager_efforts(self, q_all, qd_all, velocity_cmd, yaw_rate_cmd, xi, yaw_des, mass_hat, k_R, k_w, needs_yaw_sync,
                      arm_target=None, contact_mode=None) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        return physics_step_efforts(q_all, qd_all, velocity_cmd, yaw_rate_cmd, xi, yaw_des, mass_hat, k_R, k_w,
                                    needs_yaw_sync, self.params, self.arm, arm_target, contact_mode)

    def eager_efforts_in_place(self, efforts, q_all, qd_all, velocity_cmd, yaw_rate_cmd, xi, yaw_des, *rest) -> tuple[()]:
        """`eager_efforts` that writes its results into its inputs and returns nothing: the efforts into `efforts`
        (an `(N, J)` buffer), the new controller memory into `xi` and `yaw_des`. What the 240 Hz loop runs on a CPU:
        no output to allocate, hand out or convert at each physics step."""
        new_efforts, new_xi, new_yaw_des = self.eager_efforts(q_all, qd_all, velocity_cmd, yaw_rate_cmd, xi, yaw_des,
                                                              *rest)
        efforts.copy_(new_efforts)
        xi.copy_(new_xi)
        yaw_des.copy_(new_yaw_des)
        return ()

    @staticmethod
    def eager_airframe_state(q_all: torch.Tensor, qd_all: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        state = airframe_state_from_joints(q_all[:, :NUM_VIRTUAL_JOINTS], qd_all[:, :NUM_VIRTUAL_JOINTS])
        return state.rotation, state.angular_velocity_body

    def __call__(self, *tensors: torch.Tensor) -> StepResult:
        return StepResult(*self._run("full", tensors))

    def airframe_state(self, q_all: torch.Tensor, qd_all: torch.Tensor) -> AirframeState:
        """`airframe_state_from_joints` of the leading six joints of the whole articulation's `(N, J)` joint
        vectors, as one compiled call (read several times per control step, by the observation and the checks)."""
        rotation, angular_velocity_body = self._run("airframe_state", (q_all, qd_all))
        return AirframeState(q_all[:, :3], qd_all[:, :3], rotation, angular_velocity_body)

    def payload_update(self, memory: FlightMemory, is_grasped: torch.Tensor, is_set_down: torch.Tensor,
                       object_mass: torch.Tensor, mode: ControllerMode) -> FlightMemory:
        """`update_payload_estimate` of `memory` (once per control step); the payload-aware switches as one compiled
        call (eager, they are about 25 small ops: 64 us a control step on a CPU, docs/performance.md)."""
        if mode is not ControllerMode.PAYLOAD_AWARE:
            return update_payload_estimate(memory, self.params, is_grasped, is_set_down, object_mass, mode)
        m = memory
        xi, mass_hat, k_R, k_w, grasp_steps, payload_active = self.kernels["payload"](*(  # PAYLOAD_FIELDS
            m.xi, m.yaw_des, m.mass_hat, m.k_R, m.k_w, m.grasp_steps, m.payload_active, m.supported, is_grasped,
            is_set_down, object_mass))
        # built directly (`dataclasses.replace` walks the fields: a few microseconds at every control step)
        return FlightMemory(xi, m.yaw_des, mass_hat, k_R, k_w, grasp_steps, payload_active, supported=is_set_down)

    def efforts(self, *tensors: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """`(efforts (N, J), xi, yaw_des)` from the whole articulation's `q_all, qd_all` and the other inputs."""
        return tuple(self._run("efforts", tensors))

    def efforts_loop(self, tensors: Sequence[torch.Tensor]) -> Callable[[list[torch.Tensor]], tuple[torch.Tensor, ...]]:
        """`efforts` for the 240 Hz loop, for inputs shaped like `tensors`, taking the input list. Where a CPU package
        runs the step, it calls the package of `eager_efforts_in_place` itself: the efforts go into one buffer of the
        loop's own, returned at every call (the caller may keep a view of it, e.g. the numpy array PhysX takes), and
        the new `xi` and `yaw_des` into the input tensors, which it returns as the memory (the caller's memory
        tensors are updated in place: they must be its own). About 5 us a call less than the kernel's wrapper and
        copies of its outputs, at 12 calls per control step (docs/performance.md). The package's kernel is called
        directly where `direct_call` can read the package (about 9 us a call less again, right after a physics
        step), else through the package's runner. Without a package, or for a strided input, the pure kernel's
        fresh outputs."""
        kernel = self.kernels["efforts_in_place"]
        efforts = torch.zeros_like(tensors[0])  # (N, J), as q_all
        if kernel.aot_ok:
            kernel(efforts.clone(), *[t.clone() for t in tensors])  # builds or loads the package (on copies)
        run = kernel.package(efforts, *tensors)
        if run is None:
            return lambda inputs: self.efforts(*inputs)
        direct = kernel.direct_call(efforts, *tensors)
        step = direct if direct is not None else lambda *args: run(list(args))

        def call(inputs: list[torch.Tensor]) -> tuple[torch.Tensor, ...]:
            if not all_contiguous(inputs):  # the package reads raw memory: the wrapper makes a contiguous copy
                return self.efforts(*inputs)
            step(efforts, *inputs)
            return efforts, inputs[4], inputs[5]

        return call

    def _run(self, variant: str, tensors: tuple[torch.Tensor, ...]):
        self._last = kernel = self.kernels[variant]
        return kernel(*tensors)


_STEPS: dict[tuple, FusedPhysicsStep] = {}


def fused_physics_step(platform: PlatformSpec, device: torch.device | str, compile: bool | None = None) -> FusedPhysicsStep:
    """The process's one fused step for `platform` on `device` (shared, so it compiles once per process)."""
    compile = compile_requested() if compile is None else compile
    key = (platform, str(device), compile)
    if key not in _STEPS:
        _STEPS[key] = FusedPhysicsStep(platform, device, compile)
    return _STEPS[key]
