"""`kernels`: one shared kernel per process for each name, key, device and compile setting; a compiled call's outputs
are the caller's."""

import contextlib
from pathlib import Path

import pytest
import torch

from aerobench.accel.kernels import Kernel, hands_out_again, shared_kernel, trusted_vector_isa


def _plus_one(x: torch.Tensor) -> tuple[torch.Tensor]:
    return (x + 1,)


def test_a_shared_kernel_is_made_once_per_name_key_device_and_setting():
    kernel = shared_kernel(_plus_one, "test_plus_one", ("law", 1), [], "cpu", compile=False)
    assert shared_kernel(_plus_one, "test_plus_one", ("law", 1), [], "cpu", compile=False) is kernel
    others = [
        shared_kernel(_plus_one, "test_plus_one", ("law", 2), [], "cpu", compile=False),
        shared_kernel(_plus_one, "test_other", ("law", 1), [], "cpu", compile=False),
        shared_kernel(_plus_one, "test_plus_one", ("law", 1), [], "cpu", compile=True),
    ]
    assert all(other is not kernel for other in others) and len({id(o) for o in others}) == 3
    assert kernel.backend == "eager" and torch.equal(kernel(torch.ones(2))[0], torch.full((2,), 2.0))


def _step(x: torch.Tensor, memory: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    y = torch.sin(x) * memory + x[:, :1]
    return y, memory + y.sum(-1, keepdim=True), x[:, :2]  # the last: a view of an input


def test_a_compiled_kernels_outputs_are_the_callers_and_nothing_stays_alive(aot_cache):
    """Ahead of time, either buffer placement: what a call returns is the eager numbers and is not overwritten by
    the next call (fed back or kept), and a call keeps neither its inputs nor its outputs alive. The same graph is
    built both ways in one process, the heap first, and each build is what it asked for: only the stack build's
    package hands out its buffers again (inductor registers one wrapper class per process; `kernels._cpu_wrapper`)."""
    import weakref

    for stack_allocation in (False, True):
        kernel = Kernel(_step, "test_outputs", ("step", stack_allocation), [], "cpu", compile=True,
                        stack_allocation=stack_allocation)
        x, memory = torch.randn(1, 4), torch.randn(1, 1)
        first = kernel(x, memory)
        assert kernel.backend == "compiled ahead of time", kernel.backend
        for a, b in zip(first, _step(x, memory)):
            torch.testing.assert_close(a, b)
        kept = [t.clone() for t in first]
        second = kernel(-x, first[1])  # the memory fed back, another input
        for mine, copy, later in zip(first[:2], kept, second):
            assert torch.equal(mine, copy) and mine.data_ptr() != later.data_ptr()
        torch.testing.assert_close(second[1], _step(-x, kept[1])[1])
        assert hands_out_again(kernel.package(x, memory), [x, memory]) == stack_allocation
        inputs = [torch.randn(1, 4), torch.randn(1, 1)]
        refs = [weakref.ref(t) for t in inputs]
        outputs = [weakref.ref(t) for t in kernel(*inputs)]
        del inputs
        assert [r() is None for r in refs + outputs] == [True] * (len(refs) + len(outputs))


def test_a_package_that_hands_out_its_buffers_again_is_found():
    """`hands_out_again`: an output in the same memory at two calls (a stack-allocated package's), but not an output
    that is a view of an input, nor fresh outputs."""
    x = torch.randn(1, 4)
    buffer = torch.zeros(1, 4)

    def reuses(inputs):
        return [buffer.copy_(inputs[0] * 2), inputs[0][:, :2]]

    def fresh(inputs):
        return [inputs[0] * 2, inputs[0][:, :2]]

    assert hands_out_again(reuses, [x]) and not hands_out_again(fresh, [x])


@pytest.mark.skipif(not Path("/proc/self/maps").exists(), reason="reads the process's mapped libraries (Linux)")
def test_a_loaded_package_leaves_no_extracted_files_behind(aot_cache):
    """torch extracts a package to a fresh temporary folder at each load and never removes it; once the library is
    mapped, `load_aot` does (every worker of every job left 0.7 MB per kernel)."""
    kernel = Kernel(_step, "test_extraction", ("step",), [], "cpu", compile=True)
    kernel(torch.randn(1, 4), torch.randn(1, 1))
    assert kernel.backend == "compiled ahead of time", kernel.backend
    lines = [line.split(maxsplit=5) for line in Path("/proc/self/maps").read_text().splitlines()]
    mapped = {fields[5].removesuffix(" (deleted)") for fields in lines if len(fields) == 6}
    packages = [path for path in mapped if "/data/aotinductor/model/" in path]
    assert packages  # the package's library is mapped ...
    assert not [path for path in packages if Path(path).exists()]  # ... and its extracted files are gone


def test_builds_take_turns_and_a_build_that_waited_loads_the_package_another_built(aot_cache, monkeypatch):
    """AOTInductor writes a build's files into inductor's shared cache folder under a name taken from the code, so two
    processes building one graph at once (this module's `_step` under three keys, on two xdist workers) zipped each
    other's half-written files: a package with empty metadata (CI, a kernel left on `torch.compile`). Builds hold one
    lock across processes, and a build that waited for it loads the package the other one made instead of building."""
    import fcntl
    import shutil

    from torch._inductor.runtime.cache_dir_utils import cache_dir as inductor_cache_dir

    from aerobench.accel import kernels

    lock_file = Path(inductor_cache_dir()) / kernels.BUILD_LOCK
    real_build = torch._inductor.aoti_compile_and_package
    locked_during_build = []

    def watched_build(*args, **kwargs):
        with open(lock_file, "a") as other:  # another open file: flock sees another holder, as another process
            try:
                fcntl.flock(other, fcntl.LOCK_EX | fcntl.LOCK_NB)
                locked_during_build.append(False)
                fcntl.flock(other, fcntl.LOCK_UN)
            except BlockingIOError:
                locked_during_build.append(True)
        return real_build(*args, **kwargs)

    monkeypatch.setattr(torch._inductor, "aoti_compile_and_package", watched_build)
    first, second = aot_cache / "built_by_the_first", aot_cache / "built_while_waiting"
    monkeypatch.setenv("AEROBENCH_CACHE_DIR", str(first))
    kernel = Kernel(_plus_one, "test_build_lock", ("plus one",), [], "cpu", compile=True)
    kernel(torch.ones(2))
    assert kernel.backend == "compiled ahead of time" and locked_during_build == [True]

    @contextlib.contextmanager
    def the_other_process_finishes_while_this_one_waits():
        shutil.copytree(first, second)
        yield

    monkeypatch.setattr(kernels, "_one_build_at_a_time", the_other_process_finishes_while_this_one_waits)
    monkeypatch.setenv("AEROBENCH_CACHE_DIR", str(second))
    again = Kernel(_plus_one, "test_build_lock", ("plus one",), [], "cpu", compile=True)
    assert torch.equal(again(torch.ones(2))[0], torch.full((2,), 2.0))
    assert again.backend == "compiled ahead of time" and locked_during_build == [True]  # loaded, not built again


def _elementwise(x: torch.Tensor) -> tuple[torch.Tensor]:
    return (torch.sin(x) * 2 + 1,)


def test_a_package_is_single_threaded_whatever_the_building_process_runs(aot_cache):
    """A package built by a process with two torch threads has no OpenMP team in it: inductor would otherwise write
    the builder's thread count into the code, and every call of it, in any process, would start that many threads
    (K one-thread rollout workers on K cores then took the cores from each other)."""
    import zipfile

    old = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        kernel = Kernel(_elementwise, "test_threads", ("elementwise",), [], "cpu", compile=True)
        x = torch.randn(512, 512)  # large enough that inductor splits the loop across a team when it may
        torch.testing.assert_close(kernel(x)[0], _elementwise(x)[0])
        assert kernel.backend == "compiled ahead of time", kernel.backend
    finally:
        torch.set_num_threads(old)
    packages = list((aot_cache / "test_threads").glob("*.pt2"))
    assert len(packages) == 1
    with zipfile.ZipFile(packages[0]) as package:
        sources = [package.read(name).decode() for name in package.namelist() if name.endswith(".cpp")]
    assert sources and not any("#pragma omp parallel" in source for source in sources)


def test_inductors_isa_probes_are_answered_without_building_or_a_fresh_process(monkeypatch):
    """Inside `trusted_vector_isa` an extension probe builds nothing and starts no process (each costs a fresh Python
    importing torch, about 1.6 s here): AVX-512 VNNI and BF16 pass, AMX is declined; outside it inductor's own probe
    is back."""
    import subprocess

    from torch._inductor import cpu_vec_isa

    def no_process(*args, **kwargs):
        raise AssertionError(f"a probe started a process: {args}")

    monkeypatch.setattr(subprocess, "check_call", no_process)
    probe = cpu_vec_isa.VecISA.check_build
    with trusted_vector_isa():
        vnni, amx = cpu_vec_isa.VecAVX512VNNI(), cpu_vec_isa.VecAMX()  # fresh instances: nothing cached
        assert vnni.check_build(vnni._avx512_vnni_code) is True
        assert amx.check_build(cpu_vec_isa.VecAMX._amx_code) is False
    assert cpu_vec_isa.VecISA.check_build is probe


def test_the_answered_isa_is_the_one_inductors_probes_pick():
    """What a process that loads packages picks (answered probes) against what inductor's probes pick in a fresh
    process: the same ISA and compiler flags, so the kernels' builds and cache keys are what they were; on a CPU with
    AMX tiles the answered ISA is the best one below AMX."""
    import json
    import subprocess
    import sys

    script = """
import json, sys, torch
from torch._inductor import config, cpu_vec_isa
from aerobench.accel.kernels import trusted_vector_isa
answered = sys.argv[1] == "answered"
with config.patch({"cpp.vec_isa_ok": True}), (trusted_vector_isa() if answered else config.patch({})):
    isas = [isa for isa in cpu_vec_isa.valid_vec_isa_list() if not (answered is False and "amx" in str(isa))]
print(json.dumps([str(isas[0]), isas[0].build_arch_flags()] if isas else None))
"""
    picked = {how: json.loads(subprocess.run([sys.executable, "-c", script, how], capture_output=True, text=True,
                                             check=True).stdout.strip().splitlines()[-1])
              for how in ("answered", "probed")}
    assert picked["answered"] == picked["probed"], picked


def _step_in_place(x: torch.Tensor, memory: torch.Tensor) -> tuple[()]:
    memory.copy_(memory + torch.sin(x).sum(-1, keepdim=True))
    return ()


def test_only_a_package_that_writes_into_its_inputs_is_called_directly(aot_cache, caplog):
    """A real package of each kind: one with outputs (either buffer placement) keeps its runner, reported once with
    the line of its wrapper that `direct_call` does not read; an in-place one is called directly, with the runner's
    numbers."""
    x = torch.randn(1, 4)
    for stack_allocation in (False, True):
        kernel = Kernel(_step, "test_direct_outputs", ("step", stack_allocation), [], "cpu", compile=True,
                        stack_allocation=stack_allocation, direct=True)
        with caplog.at_level("WARNING"):
            kernel(x, torch.ones(1, 1))
        assert kernel.direct_call(x, torch.ones(1, 1)) is None
    assert caplog.text.count("direct call of the test direct outputs failed (UnsupportedPackage: run_impl does more "
                             "than one in-place kernel") == 2
    kernel = Kernel(_step_in_place, "test_direct_in_place", "in place", [], "cpu", compile=True,
                    stack_allocation=True, direct=True)
    memory = torch.ones(1, 1)
    kernel(x, memory.clone())
    direct = kernel.direct_call(x, memory)
    assert direct is not None
    by_runner, by_direct = memory.clone(), memory.clone()
    kernel.package(x, by_runner)([x, by_runner])
    direct(x, by_direct)
    assert torch.equal(by_direct, by_runner) and not torch.equal(by_direct, memory)
