"""The fused physics step: the same numbers as the laws it chains, compiled or not, and no host synchronization."""

import gymnasium as gym
import pytest
import torch

import aerobench.envs  # noqa: F401
from aerobench.accel import kernels
from aerobench.envs.control.arm import ArmParams, arm_servo_torques, arm_weight_feedforward_body
from aerobench.envs.control.flight import FlightMemory, FlightParams, flight_step
from aerobench.envs.control.fused import FusedPhysicsStep, physics_step
from aerobench.envs.control.payload import ControllerMode, update_payload_estimate
from aerobench.envs.control.virtual_joints import airframe_state_from_joints, joint_efforts_from_wrench
from aerobench.envs.platforms import get_platform
from tests.envs.host_sync import NoHostSync

# every test here builds its packages into a cache of this run's (never the user's)
pytestmark = [pytest.mark.usefixtures("aot_cache"), pytest.mark.xdist_group("aot_packages")]  # one worker builds each package once (conftest)


def _inputs(platform: str, n: int = 3, seed: int = 0):
    g = torch.Generator().manual_seed(seed)
    spec = get_platform(platform)
    params = FlightParams.from_platform(spec)
    memory = FlightMemory.initial(n, params)
    memory.xi = torch.randn(n, 3, generator=g) * 0.1
    memory.yaw_des = torch.randn(n, generator=g)
    memory.mass_hat = memory.mass_hat + torch.tensor([0.0, 0.4] + [0.2] * max(n - 2, 0))[:n]  # carrying a payload in some envs
    joints = 6 + (3 if spec.arm else 0)
    q, qd = torch.randn(n, joints, generator=g) * 0.2, torch.randn(n, joints, generator=g) * 0.2
    v_cmd, yaw_rate = torch.randn(n, 3, generator=g), torch.randn(n, generator=g)
    sync = torch.tensor([True] + [False] * (n - 1))
    arm = ArmParams.from_spec(spec.arm, spec.gripper) if spec.arm else None
    arm_target = torch.randn(n, 3, generator=g) * 0.3 if arm else None
    contact = torch.tensor([False, True] + [False] * (n - 2))[:n] if arm else None
    return spec, params, memory, q, qd, v_cmd, yaw_rate, sync, arm, arm_target, contact


@pytest.mark.parametrize("platform", ["gripper", "arm"])
def test_fused_step_is_the_laws_it_chains(platform):
    spec, params, memory, q, qd, v_cmd, yaw_rate, sync, arm, arm_target, contact = _inputs(platform)
    result = physics_step(q, qd, v_cmd, yaw_rate, memory.xi, memory.yaw_des, memory.mass_hat, memory.k_R, memory.k_w,
                          sync, params, arm, arm_target, contact)
    # the unfused reference, as the body controller ran it before fusion
    state = airframe_state_from_joints(q[:, :6], qd[:, :6])
    memory.yaw_des = torch.where(sync, state.yaw, memory.yaw_des)
    feedforward = None
    if arm is not None:
        feedforward = arm_weight_feedforward_body(state.rotation, q[:, 6:], arm, params.gravity, memory.mass_hat - params.mass)
        feedforward = torch.where(contact[:, None], torch.zeros_like(feedforward), feedforward)
    out, memory = flight_step(state, v_cmd, yaw_rate, memory, params, feedforward)
    efforts = joint_efforts_from_wrench(q[:, :6], out.force_world, out.torque_world)
    if arm is not None:
        efforts = torch.cat([efforts, arm_servo_torques(q[:, 6:], qd[:, 6:], arm_target, arm, contact)], -1)
    assert torch.equal(result.efforts, efforts)
    assert torch.equal(result.xi, memory.xi) and torch.equal(result.yaw_des, memory.yaw_des)
    assert torch.equal(result.output().rotor_thrusts, out.rotor_thrusts)
    assert torch.equal(result.state(q, qd).rotation, state.rotation)
    assert torch.equal(result.state(q, qd).position, state.position)
    # the reset env took its own heading (then one step of the commanded yaw rate)
    assert float(result.yaw_des[0]) == pytest.approx(float(state.yaw[0] + yaw_rate[0] * params.dt), abs=1e-6)


def _tensors(platform: str, seed: int = 1, n: int = 3):
    spec, params, memory, q, qd, v_cmd, yaw_rate, sync, arm, arm_target, contact = _inputs(platform, n, seed)
    tensors = [q, qd, v_cmd, yaw_rate, memory.xi, memory.yaw_des, memory.mass_hat, memory.k_R, memory.k_w, sync]
    return spec, tensors + ([arm_target, contact] if arm is not None else [])


@pytest.mark.parametrize("platform, n", [("gripper", 1), ("arm", 3)])  # one env: the flight test below reuses it
def test_ahead_of_time_step_matches_the_eager_one(platform, n, aot_cache):
    spec, tensors = _tensors(platform, n=n)
    step = FusedPhysicsStep(spec, "cpu", compile=True)
    compiled, eager = step(*tensors), step.eager(*tensors)
    assert step.backend == "compiled ahead of time", step.backend  # this machine has a C++ compiler: no fallback
    for name, a, b in zip(compiled._fields, compiled, eager):
        torch.testing.assert_close(a, b, rtol=1e-5, atol=1e-5, msg=name)
    assert len(list((aot_cache / "physics_step").glob("*.pt2"))) >= 1
    # a second process (here: a second step object) loads the package instead of building it again
    def no_build(*args, **kwargs):
        raise AssertionError("built again")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(torch._inductor, "aoti_compile_and_package", no_build)
        again = FusedPhysicsStep(spec, "cpu", compile=True)
        assert torch.equal(again(*tensors).efforts, compiled.efforts) and again.backend == "compiled ahead of time"


@pytest.mark.parametrize("platform", ["gripper", "arm"])
def test_the_lean_step_and_the_airframe_state_match_the_full_step(platform, aot_cache):
    """What the body controller runs every physics step (whole joint vectors in, every joint's effort out, the
    fingers' zero) and the compiled airframe state are the full step's numbers, compiled ahead of time or eager."""
    spec, tensors = _tensors(platform, n=1)
    q, qd = tensors[0], tensors[1]
    fingers = torch.randn(1, 2)  # the articulation's trailing finger joints, which the controller leaves to PhysX
    q_all, qd_all = torch.cat([q, fingers], -1), torch.cat([qd, -fingers], -1)
    step = FusedPhysicsStep(spec, "cpu", compile=True)
    full = step.eager(*tensors)
    for efforts_fn, state_fn in ((step.efforts, step.airframe_state),
                                 (step.eager_efforts, lambda a, b: step.eager_airframe_state(a, b))):
        efforts, xi, yaw_des = efforts_fn(q_all, qd_all, *tensors[2:])
        assert efforts.shape == q_all.shape and torch.equal(efforts[:, q.shape[1]:], torch.zeros(1, 2))
        torch.testing.assert_close(efforts[:, :q.shape[1]], full.efforts, rtol=1e-5, atol=1e-5)
        torch.testing.assert_close(xi, full.xi, rtol=1e-5, atol=1e-6)
        torch.testing.assert_close(yaw_des, full.yaw_des, rtol=1e-5, atol=1e-6)
        state = state_fn(q_all, qd_all)
        rotation, omega = (state.rotation, state.angular_velocity_body) if hasattr(state, "rotation") else state
        torch.testing.assert_close(rotation, full.rotation, rtol=1e-5, atol=1e-6)
        torch.testing.assert_close(omega, full.angular_velocity_body, rtol=1e-5, atol=1e-6)
    assert step.backend == "compiled ahead of time", step.backend


def test_a_compiled_call_keeps_nothing_alive_and_its_outputs_are_its_own(aot_cache):
    """The body controller calls the step 240 times per simulated second for days of generation and training: a
    call must not keep its inputs (an AOTInductor runner option once held every call's input list: 30 MB per 100k
    calls), and what it returns must not be overwritten by the next call (the controller memory is fed back; a
    package with stack-allocated intermediates hands out the same output buffers every time)."""
    import weakref

    spec, tensors = _tensors("gripper", n=1)
    step = FusedPhysicsStep(spec, "cpu", compile=True)
    fingers = torch.randn(1, 2)
    inputs = [torch.cat([tensors[0], fingers], -1), torch.cat([tensors[1], -fingers], -1), *(t.clone() for t in tensors[2:])]
    step.efforts(*inputs)  # builds or loads the package
    assert step.backend == "compiled ahead of time", step.backend
    first = step.efforts(*inputs)
    kept = [t.clone() for t in first]
    inputs[2] = -inputs[2]  # another velocity command: other efforts
    second = step.efforts(*inputs)
    assert not torch.equal(first[0], second[0])
    for mine, copy, later in zip(first, kept, second):
        assert torch.equal(mine, copy) and mine.data_ptr() != later.data_ptr()
    refs = [weakref.ref(t) for t in inputs]
    outputs = [weakref.ref(t) for t in step.efforts(*inputs)]
    del inputs
    assert [r() is None for r in refs + outputs] == [True] * (len(refs) + len(outputs))


def test_the_240_hz_loop_calls_the_package_itself_with_the_kernels_numbers(aot_cache):
    """`efforts_loop`, what the body controller calls at every physics step after the first: the in-place package
    itself where one runs, with the pure kernel's numbers, the efforts written into the loop's own buffer and the new
    controller memory into the memory tensors it was given (both returned as they are); a non-contiguous input goes through the pure kernel's wrapper (the
    package reads raw memory); without a package, the pure kernel."""
    spec, tensors = _tensors("gripper", n=1)
    fingers = torch.randn(1, 2)
    inputs = [torch.cat([tensors[0], fingers], -1), torch.cat([tensors[1], -fingers], -1), *(t.clone() for t in tensors[2:])]
    step = FusedPhysicsStep(spec, "cpu", compile=True)
    before = [t.clone() for t in inputs]
    loop = step.efforts_loop(inputs)  # builds or loads the package (on copies: the inputs are untouched)
    assert all(torch.equal(a, b) for a, b in zip(inputs, before))
    assert step.kernels["efforts_in_place"].package(*inputs) is not None
    assert step.kernels["efforts_in_place"].direct_call(torch.zeros_like(inputs[0]), *inputs) is not None
    buffers = []
    for command in (1.0, -1.0):  # two calls, the second with another velocity command and the memory it left
        inputs[2] = command * before[2]
        expected = step.efforts(*[t.clone() for t in inputs])
        looped = loop(inputs)
        assert looped[1] is inputs[4] and looped[2] is inputs[5]  # the memory, updated in place
        buffers.append(looped[0])
        for a, b in zip(looped, expected):
            torch.testing.assert_close(a, b, rtol=1e-6, atol=1e-6)
    assert buffers[0] is buffers[1]  # the efforts: written into the loop's own buffer at each call
    assert not torch.equal(inputs[4], before[4])  # the integrator moved
    strided = [t.clone() for t in inputs]
    strided[4] = torch.stack([inputs[4], inputs[4]], -1)[..., 0]  # xi, the same values in a strided view
    assert not strided[4].is_contiguous() and torch.equal(strided[4], inputs[4])
    assert all(torch.equal(a, b) for a, b in zip(loop(strided), step.efforts(*inputs)))
    eager = FusedPhysicsStep(spec, "cpu", compile=False)
    assert eager.kernels["efforts_in_place"].package(*inputs) is None
    assert all(torch.equal(a, b) for a, b in zip(eager.efforts_loop(inputs)(inputs), eager.eager_efforts(*inputs)))


def _loop_run(step: FusedPhysicsStep, inputs: list[torch.Tensor], calls: int = 5) -> list[torch.Tensor]:
    """The loop's efforts and memory after `calls` chained calls, each with another velocity command."""
    inputs = [t.clone() for t in inputs]
    loop, history = step.efforts_loop(inputs), []
    for i in range(calls):
        inputs[2] = inputs[2] * (-1.0) ** i + 0.1
        history += [t.clone() for t in loop(inputs)]
    return history


def test_the_240_hz_loop_calls_the_kernel_directly_with_the_runners_numbers(aot_cache, monkeypatch):
    """The arm platform's in-place package (a float and a bool input more): called directly, its kernel writes what
    the package's runner writes, to the bit, over chained calls that feed the memory back."""
    spec, tensors = _tensors("arm", n=1)
    fingers = torch.randn(1, 2)
    inputs = [torch.cat([tensors[0], fingers], -1), torch.cat([tensors[1], -fingers], -1), *tensors[2:]]
    random_state = torch.get_rng_state()
    direct = FusedPhysicsStep(spec, "cpu", compile=True)
    by_direct = _loop_run(direct, inputs)
    assert torch.equal(torch.get_rng_state(), random_state)  # the entry's check drew from a generator of its own
    assert direct.kernels["efforts_in_place"].direct_call(torch.zeros_like(inputs[0]), *inputs) is not None
    monkeypatch.setenv("AEROBENCH_DIRECT_CALL", "0")
    runner = FusedPhysicsStep(spec, "cpu", compile=True)
    by_runner = _loop_run(runner, inputs)
    assert runner.kernels["efforts_in_place"].direct_call(torch.zeros_like(inputs[0]), *inputs) is None
    assert len(by_direct) == len(by_runner) == 15
    assert all(torch.equal(a, b) for a, b in zip(by_direct, by_runner))
    assert not torch.equal(by_direct[0], by_direct[3])  # the calls differ: the comparison is not of one value


def test_a_package_that_cannot_be_called_directly_keeps_its_runner(aot_cache, monkeypatch, caplog):
    """Where the package is not of the form `direct_call` reads, or its direct call fails or writes other numbers
    than the runner's, the loop calls the runner of the same package, and says so once."""
    spec, tensors = _tensors("gripper", n=1, seed=4)
    fingers = torch.randn(1, 2)
    inputs = [torch.cat([tensors[0], fingers], -1), torch.cat([tensors[1], -fingers], -1), *tensors[2:]]
    with monkeypatch.context() as m:
        m.setenv("AEROBENCH_DIRECT_CALL", "0")
        reference = _loop_run(FusedPhysicsStep(spec, "cpu", compile=True), inputs)  # the runner's

    def unsupported(*args, **kwargs):
        raise kernels.UnsupportedPackage("run_impl calls more than one kernel")

    def writes_zeros(*args, **kwargs):
        def entry(*tensors):
            for t in tensors:
                if t.is_floating_point():
                    t.zero_()
        return entry

    def raises(*args, **kwargs):
        def entry(*tensors):
            raise RuntimeError("requires 12 args")
        return entry

    for entry, reason in ((unsupported, "UnsupportedPackage: run_impl calls more than one kernel"),
                          (writes_zeros, "UnsupportedPackage: its results differ from the runner's"),
                          (raises, "RuntimeError: requires 12 args")):
        monkeypatch.setattr(kernels, "direct_entry", entry)
        step = FusedPhysicsStep(spec, "cpu", compile=True)
        with caplog.at_level("WARNING"):
            looped = _loop_run(step, inputs)
        assert step.kernels["efforts_in_place"].direct_call(torch.zeros_like(inputs[0]), *inputs) is None
        assert step.kernels["efforts_in_place"].backend == "compiled ahead of time"  # the package stays
        assert f"direct call of the physics step failed ({reason}); calling the package's " \
               "runner" in caplog.text
        assert all(torch.equal(a, b) for a, b in zip(looped, reference))


def test_the_compiled_payload_switches_are_the_eager_ones(aot_cache):
    """`FusedPhysicsStep.payload_update`, once per control step: compiled ahead of time, the memory the eager
    switches give over grasps, a set-down and a lost grasp, in three envs at once; the nominal controller's too."""
    spec = get_platform("gripper")
    params = FlightParams.from_platform(spec)
    compiled = FusedPhysicsStep(spec, "cpu", compile=True)
    mass = torch.tensor([0.37, 0.15, 0.6])
    T, F = True, False
    steps = [  # (is_grasped, is_set_down) per env
        ([T, T, F], [F, F, F]), ([T, T, T], [F, F, F]), ([T, T, T], [F, F, F]), ([T, F, T], [F, F, F]),
        ([T, F, T], [T, F, F]), ([T, T, F], [T, F, F]), ([F, T, T], [F, F, F]),
    ]
    for mode in ControllerMode:
        a = FlightMemory.initial(3, params)
        a.xi = torch.tensor([[0.1, -0.2, 0.3], [0.0, 0.1, -0.4], [0.2, 0.2, 0.2]])
        b = FlightMemory(*(getattr(a, f).clone() for f in a.__dataclass_fields__))
        history = []
        for grasped, set_down in steps:
            grasped, set_down = torch.tensor(grasped), torch.tensor(set_down)
            a = compiled.payload_update(a, grasped, set_down, mass, mode)
            b = update_payload_estimate(b, params, grasped, set_down, mass, mode)
            history.append(a)
            for name in a.__dataclass_fields__:
                assert torch.equal(getattr(a, name), getattr(b, name)), (mode, name)
        aware = mode is ControllerMode.PAYLOAD_AWARE
        # after four steps the first and third envs carry their load (the second lost its grasp); the first is set
        # down at the fifth: its vertical integral resets once
        assert history[3].payload_active.tolist() == [aware, False, aware]
        assert (float(history[4].xi[0, 2]) == 0.0) == aware and float(history[4].xi[2, 2]) == pytest.approx(0.2)
        assert history[-1].grasp_steps.tolist() == [0, 2, 1]
    assert compiled.kernels["payload"].backend == "compiled ahead of time", compiled.kernels["payload"].backend


def test_torch_compiled_step_matches_the_eager_one():
    """The path of GPUs, and of CPUs where the ahead-of-time build fails."""
    spec, tensors = _tensors("arm")
    step = FusedPhysicsStep(spec, "cpu", compile=True)
    for kernel in step.kernels.values():
        kernel.aot_ok = False
    compiled, eager = step(*tensors), step.eager(*tensors)
    assert step.backend == "compiled", step.backend
    for name, a, b in zip(compiled._fields, compiled, eager):
        torch.testing.assert_close(a, b, rtol=1e-5, atol=1e-5, msg=name)


def test_a_failed_ahead_of_time_build_falls_back_to_torch_compile(monkeypatch, caplog):
    spec, tensors = _tensors("gripper", seed=2)

    def broken(*args, **kwargs):
        raise RuntimeError("no linker")

    monkeypatch.setattr(kernels, "load_aot", broken)
    monkeypatch.setattr(torch, "compile", lambda fn, **kw: fn)  # stands in for a working torch.compile
    step = FusedPhysicsStep(spec, "cpu", compile=True)
    with caplog.at_level("WARNING"):
        result = step(*tensors)
    assert step.backend == "compiled" and torch.equal(result.efforts, step.eager(*tensors).efforts)
    assert "ahead-of-time compilation of the physics step failed (RuntimeError: no linker)" in caplog.text


def test_a_broken_compiler_falls_back_to_the_eager_step(monkeypatch):
    spec, params, memory, q, qd, v_cmd, yaw_rate, sync, *_ = _inputs("gripper")

    def broken(*args, **kwargs):
        raise RuntimeError("no C++ compiler")

    monkeypatch.setattr(kernels, "load_aot", broken)
    monkeypatch.setattr(torch, "compile", lambda fn, **kw: broken)
    step = FusedPhysicsStep(spec, "cpu", compile=True)
    tensors = [q, qd, v_cmd, yaw_rate, memory.xi, memory.yaw_des, memory.mass_hat, memory.k_R, memory.k_w, sync]
    result = step(*tensors)
    assert step.backend.startswith("eager (fallback: RuntimeError: no C++ compiler")
    assert torch.equal(result.efforts, step.eager(*tensors).efforts)


def test_the_detector_catches_a_sync():
    with pytest.raises(AssertionError, match="host synchronization"), NoHostSync():
        if torch.ones(2).any():
            pass


@pytest.mark.parametrize("platform", ["gripper", "arm"])
def test_the_physics_step_path_makes_no_host_sync(platform):
    """The body controller's `before_simulation_step` (joint read, fused step, effort write) on physx_cpu, right after
    a reset (the heading sync) and in flight; on physx_cuda any such op would stall the whole batch."""
    env = gym.make("AeroFly-v1", obs_mode="state_dict", platform=platform)
    env.reset(seed=0)
    controller = env.unwrapped.agent.body_controller
    controller.step_fn = FusedPhysicsStep(env.unwrapped.platform, "cpu", compile=False)  # dispatch-visible ops
    controller.set_action(torch.full((1, controller.single_action_space.shape[0]), 0.3))
    with NoHostSync():
        for _ in range(3):
            controller.before_simulation_step()
    assert bool(torch.isfinite(controller.memory.xi).all())
    env.close()


def test_a_compiled_flight_follows_the_eager_one():
    """The same 3 s of flight (climb, turn, translate) with the compiled and the eager step: same track to 1 mm."""
    tracks = {}
    for compile in (False, True):
        env = gym.make("AeroFly-v1", obs_mode="state_dict")
        env.reset(seed=0)
        base = env.unwrapped
        base.agent.body_controller.step_fn = FusedPhysicsStep(base.platform, "cpu", compile=compile)
        positions = []
        for t in range(60):
            action = torch.tensor([[0.4 if t > 20 else 0.0, 0.0, 0.5 if t < 20 else 0.0, 0.3, 1.0]])
            env.step(action)
            positions.append(base.agent.airframe_state().position[0].clone())
        tracks[compile] = torch.stack(positions)
        assert base.agent.body_controller.step_fn.backend == ("compiled ahead of time" if compile else "eager")
        env.close()
    assert float((tracks[True] - tracks[False]).norm(dim=-1).max()) < 1e-3
    assert float((tracks[True][-1] - tracks[True][0]).norm()) > 0.2  # it really flew
