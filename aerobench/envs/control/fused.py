"""One physics step of the airframe as a single fused kernel: joints in, joint efforts and telemetry out.

`physics_step` chains the laws of `virtual_joints`, `flight` and `arm` (each stays a readable function, one per spec
equation) with no Python branch on a tensor value and no tensor-to-Python conversion, so the same code is a
CUDA-graph capturable step on physx_cuda and one compiled kernel on a CPU. With one env on a CPU the eager step is
about 60 small torch ops whose dispatch, not arithmetic, is the cost; `fused_physics_step` returns the step compiled
by `torch.compile` (inductor, whose on-disk cache makes later processes load it in seconds), shared by every env of
the same platform in the process, and falls back to the eager function, reported once, where compilation fails.

On a CPU the step is compiled ahead of time instead (AOTInductor, `torch.export` of the same function for the input
shapes seen at the first call): a call is then one C++ entry, without dynamo's guards and wrappers (on the 2-core
machine about 45 instead of 210 microseconds per physics step). The package is cached on disk under
`$AEROBENCH_CACHE_DIR` (default `~/.cache/aerobench`), keyed by the source of the control laws, the platform, the
shapes, torch and the CPU's vector ISA; where it cannot be built or loaded, `torch.compile` runs (reported once).

`AEROBENCH_COMPILE=0` forces the eager path; `AEROBENCH_COMPILE_MODE=reduce-overhead` asks inductor to capture the
step in a CUDA graph on physx_cuda (docs/gpu.md).
"""

from __future__ import annotations

import hashlib
import logging
import os
import tempfile
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple

import torch

from ..platforms import PlatformSpec
from .arm import ArmParams, arm_servo_torques, arm_weight_feedforward_body
from .flight import FlightOutput, FlightParams, flight_laws
from .virtual_joints import NUM_VIRTUAL_JOINTS, AirframeState, airframe_state_from_joints, joint_efforts_from_wrench

log = logging.getLogger(__name__)
# Trust the CPU's advertised vector ISA instead of proving it: inductor otherwise builds a test library and loads it
# in a fresh Python process per ISA, about 20 s at every process start on this 2-core machine, cache or not.
INDUCTOR_OPTIONS = {"cpp.vec_isa_ok": True, "cpp_wrapper": True}
# An AOTInductor package is C++ throughout. The step is a few hundred flops on (N, 3) tensors, so what a call costs is
# its bookkeeping: a heap tensor per intermediate buffer and an ATen call per small matmul. The small matmuls are
# decomposed into the fused kernel (inductor's own pass: on a CPU it applies to a batch of one, physx_cpu's N), and
# the intermediates live on the stack: a call about 3x cheaper (docs/performance.md), the outputs copied
# (`_owned`: such a package hands out the same output buffers at every call). The minimal array-ref interface, which
# goes with stack allocation in inductor's examples, also kept every call's inputs alive through the Python runner
# (30 MB per 100k calls); tests/envs/control/test_fused.py checks that a call leaves nothing behind and that outputs
# do not alias.
AOT_INDUCTOR_OPTIONS = {
    "cpp.vec_isa_ok": True,
    "aot_inductor.allow_stack_allocation": True,
    "post_grad_fusion_options": {"decompose_mm_pass": {}},
}


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


def cache_dir() -> Path:
    """Where compiled artifacts are kept across processes: `$AEROBENCH_CACHE_DIR`, else `~/.cache/aerobench`."""
    root = os.environ.get("AEROBENCH_CACHE_DIR")
    return Path(root) if root else Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "aerobench"


def _control_source_digest() -> str:
    """The source of every module the step chains (this package and the platform constants): a changed law is a new
    package, never a stale one."""
    here = Path(__file__).resolve().parent
    files = sorted(here.glob("*.py")) + [here.parent / "platforms.py"]
    h = hashlib.sha256()
    for f in files:
        h.update(f.name.encode() + f.read_bytes())
    return h.hexdigest()


class _ExportedStep(torch.nn.Module):
    def __init__(self, step: Callable):
        super().__init__()
        self.step = step

    def forward(self, *tensors: torch.Tensor) -> tuple[torch.Tensor, ...]:
        return tuple(self.step(*tensors))


def load_aot_step(step: Callable, tensors: list[torch.Tensor], platform: PlatformSpec, variant: str = "full") -> Callable:
    """`step` compiled ahead of time for the shapes of `tensors` (CPU), built once per key and loaded from the cache:
    returns a function of the flat tensor list that returns the flat list of outputs. `variant` names which function
    of the step `step` is (its outputs), part of the key."""
    key = hashlib.sha256(repr((
        _control_source_digest(), variant, repr(platform), [(tuple(t.shape), str(t.dtype)) for t in tensors],
        torch.__version__, torch.backends.cpu.get_cpu_capability(), AOT_INDUCTOR_OPTIONS,
    )).encode()).hexdigest()[:24]
    path = cache_dir() / "physics_step" / f"{key}.pt2"
    if not path.is_file():
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(suffix=".pt2", dir=path.parent)
        os.close(fd)
        try:  # built beside its final name and renamed: a concurrent process sees a whole package or none
            with warnings.catch_warnings():  # torch's own pytree deprecation notes, nothing a user can act on
                warnings.simplefilter("ignore", FutureWarning)
                program = torch.export.export(_ExportedStep(step), tuple(tensors), strict=False)
                torch._inductor.aoti_compile_and_package(program, package_path=tmp, inductor_configs=dict(AOT_INDUCTOR_OPTIONS))
            os.replace(tmp, path)
        finally:
            if os.path.exists(tmp):
                os.remove(tmp)
    # Loading checks the package against the CPU's vector ISA; trust the advertised one here too (the key has it).
    with torch._inductor.config.patch(AOT_INDUCTOR_OPTIONS):
        return torch._inductor.aoti_load_package(str(path)).loader.run


def compile_requested() -> bool:
    return os.environ.get("AEROBENCH_COMPILE", "1").strip().lower() not in ("0", "false", "no", "off")


class FusedPhysicsStep:
    """`physics_step` for one platform, its parameters bound: call with the tensors only (the arm platform adds
    `arm_target` and `contact_mode`) for the full `StepResult`, or `efforts(...)` with the whole articulation's joints
    for what the body controller needs every physics step (`physics_step_efforts`). Each is compiled on its first call
    (ahead of time on a CPU, else `torch.compile`); on any compiler failure the next option, reported once. `backend`
    says which ran last: "compiled ahead of time", "compiled", "eager" (asked for) or "eager (fallback: <reason>)".
    """

    _reported: set[tuple[str, str]] = set()

    def __init__(self, platform: PlatformSpec, device: torch.device | str, compile: bool):
        self.platform = platform
        self.params = FlightParams.from_platform(platform, device)
        self.arm = ArmParams.from_spec(platform.arm, platform.gripper, device) if platform.arm else None
        self.backend = "not run yet" if compile else "eager"
        self._compile = compile
        self._mode = os.environ.get("AEROBENCH_COMPILE_MODE") or None
        self.cuda_graphs = compile and self._mode is not None and "reduce-overhead" in self._mode and str(device).startswith("cuda")
        self._compiled: dict[str, Callable | None] = {}  # per variant: torch.compile's function, None once it failed
        self._aot: dict[tuple, Callable] = {}  # per variant and input shapes: one env per process on physx_cpu
        self._aot_ok = compile and str(device) == "cpu" and self._mode is None
        self._fast: dict[str, tuple[torch.Size, Callable]] = {}  # per variant: the loaded package for the shapes seen

    def eager(self, q, qd, velocity_cmd, yaw_rate_cmd, xi, yaw_des, mass_hat, k_R, k_w, needs_yaw_sync,
              arm_target=None, contact_mode=None) -> StepResult:
        return physics_step(q, qd, velocity_cmd, yaw_rate_cmd, xi, yaw_des, mass_hat, k_R, k_w, needs_yaw_sync,
                            self.params, self.arm, arm_target, contact_mode)

    def eager_efforts(self, q_all, qd_all, velocity_cmd, yaw_rate_cmd, xi, yaw_des, mass_hat, k_R, k_w, needs_yaw_sync,
                      arm_target=None, contact_mode=None) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        return physics_step_efforts(q_all, qd_all, velocity_cmd, yaw_rate_cmd, xi, yaw_des, mass_hat, k_R, k_w,
                                    needs_yaw_sync, self.params, self.arm, arm_target, contact_mode)

    @staticmethod
    def eager_airframe_state(q_all: torch.Tensor, qd_all: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        state = airframe_state_from_joints(q_all[:, :NUM_VIRTUAL_JOINTS], qd_all[:, :NUM_VIRTUAL_JOINTS])
        return state.rotation, state.angular_velocity_body

    def __call__(self, *tensors: torch.Tensor) -> StepResult:
        return StepResult(*self._run("full", self.eager, tensors))

    def airframe_state(self, q_all: torch.Tensor, qd_all: torch.Tensor) -> AirframeState:
        """`airframe_state_from_joints` of the leading six joints of the whole articulation's `(N, J)` joint
        vectors, as one compiled call (read several times per control step, by the observation and the checks)."""
        rotation, angular_velocity_body = self._run("airframe_state", self.eager_airframe_state, (q_all, qd_all))
        return AirframeState(q_all[:, :3], qd_all[:, :3], rotation, angular_velocity_body)

    def efforts(self, *tensors: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """`(efforts (N, J), xi, yaw_des)` from the whole articulation's `q_all, qd_all` and the other inputs."""
        return tuple(self._run("efforts", self.eager_efforts, tensors))

    def _run(self, variant: str, fn: Callable, tensors: tuple[torch.Tensor, ...]):
        fast = self._fast.get(variant)
        if fast is not None and tensors[0].shape == fast[0]:  # the shapes follow from q's (N and the joint count)
            self.backend = "compiled ahead of time"
            return _owned(fast[1]([t if t.is_contiguous() else t.contiguous() for t in tensors]))
        if self._aot_ok:
            shapes = (variant, *(t.shape for t in tensors))
            run = self._aot.get(shapes)
            if run is None:
                try:
                    run = self._aot[shapes] = load_aot_step(fn, list(tensors), self.platform, variant)
                except Exception as exc:  # noqa: BLE001 - torch.compile (or eager) is the same function
                    self._aot_ok = False
                    self._report("ahead-of-time compilation", exc, "running torch.compile instead")
            if run is not None:
                self._fast[variant] = (tensors[0].shape, run)
                self.backend = "compiled ahead of time"
                return _owned(run([t if t.is_contiguous() else t.contiguous() for t in tensors]))
        compiled = self._compiled_fn(variant, fn)
        if compiled is None:
            return fn(*tensors)
        if self.cuda_graphs:  # a captured graph reuses its output buffers at the next replay: keep copies
            torch.compiler.cudagraph_mark_step_begin()
        try:
            result = compiled(*tensors)
        except Exception as exc:  # noqa: BLE001
            self._fall_back(variant, exc)
            return fn(*tensors)
        self.backend = "compiled"
        return tuple(t.clone() for t in result) if self.cuda_graphs else result

    def _compiled_fn(self, variant: str, fn: Callable) -> Callable | None:
        if not self._compile:
            return None
        if variant not in self._compiled:
            try:
                self._compiled[variant] = torch.compile(fn, dynamic=False, fullgraph=True, mode=self._mode,
                                                        options=INDUCTOR_OPTIONS)
            except Exception as exc:  # noqa: BLE001 - e.g. no compiler backend: the eager step is the same function
                self._fall_back(variant, exc)
        return self._compiled[variant]

    def _fall_back(self, variant: str, exc: Exception) -> None:
        reason = self._report("torch.compile", exc, "running the eager step (same numbers, slower on CPU)")
        self.backend, self._compiled[variant] = f"eager (fallback: {reason})", None

    @staticmethod
    def _report(what: str, exc: Exception, instead: str) -> str:
        first_line = str(exc).splitlines()[0] if str(exc) else ""
        reason = f"{type(exc).__name__}: {first_line}"[:200]
        if (what, reason) not in FusedPhysicsStep._reported:
            FusedPhysicsStep._reported.add((what, reason))
            log.warning("aerobench: %s of the physics step failed (%s); %s. AEROBENCH_COMPILE=0 skips the attempt.",
                        what, reason, instead)
        return reason


def _owned(outputs: list[torch.Tensor]) -> list[torch.Tensor]:
    """A package with stack-allocated intermediates returns the same output buffers at every call: copies, so that
    the controller memory fed back (and anything a caller keeps) is not overwritten by the next call (about a
    microsecond each)."""
    return [t.clone() for t in outputs]


_STEPS: dict[tuple, FusedPhysicsStep] = {}


def fused_physics_step(platform: PlatformSpec, device: torch.device | str, compile: bool | None = None) -> FusedPhysicsStep:
    """The process's one fused step for `platform` on `device` (shared, so it compiles once per process)."""
    compile = compile_requested() if compile is None else compile
    key = (platform, str(device), compile)
    if key not in _STEPS:
        _STEPS[key] = FusedPhysicsStep(platform, device, compile)
    return _STEPS[key]
