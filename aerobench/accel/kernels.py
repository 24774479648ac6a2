"""A pure function of tensors run as one compiled call, with the eager function as its fallback.

With one env per process (physx_cpu) a per-step function of a few hundred small torch ops costs their dispatch, not
their arithmetic. `Kernel` runs such a function (no Python branch on a tensor value, no tensor-to-Python conversion)
as one call:

- on a CPU, compiled ahead of time (AOTInductor: `torch.export` of the function for the input shapes seen at the
  first call, then one C++ entry per call, without dynamo's guards and wrappers). The package is cached on disk
  under `$AEROBENCH_CACHE_DIR` (default `~/.cache/aerobench`), keyed by the source of the modules the function
  chains, the caller's key, the shapes (a dimension named in `dynamic` is left free), torch and the CPU's vector ISA;
- elsewhere, or where the ahead-of-time build fails, `torch.compile` (inductor);
- where that fails too, the eager function: the same numbers, reported once.

A kernel made with `direct=True` (the 240 Hz flight step, which writes its results into its inputs) is also offered
without the package's runner: `direct_call` reads the package's generated C++ and calls its one fused function from
Python, checked against the runner to the bit first (`Kernel.direct_call`); `AEROBENCH_DIRECT_CALL=0` keeps the runner.

`AEROBENCH_COMPILE=0` forces the eager path (the tests' default); `AEROBENCH_COMPILE_MODE=reduce-overhead` asks
inductor to capture the call in a CUDA graph on a GPU (docs/gpu.md).
"""

from __future__ import annotations

import hashlib
import logging
import os
import shutil
import tempfile
import warnings
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import NamedTuple

import torch

from ..file_lock import exclusive
from .direct_call import UnsupportedPackage, direct_entry

log = logging.getLogger(__name__)
# Trust the CPU's advertised vector ISA instead of proving it: inductor otherwise builds a test library and loads it
# in a fresh Python process per ISA, about 20 s at every process start on this 2-core machine, cache or not (the
# extensions it probes even so are answered by `trusted_vector_isa`, around every ahead-of-time build and load).
# One thread in the generated C++: inductor otherwise writes the building process's torch thread count into the code
# (`#pragma omp parallel num_threads(n)`), and every call of such a kernel starts a team of n threads even in a
# one-thread process. A package built by a two-thread process (`aerobench demo`) and then run by K rollout workers,
# one per core, had their spinning OpenMP threads take the cores from each other: PPO with K = 2 at 0.56x K = 1 in
# `make bench` (docs/performance.md). These kernels work on a batch of one env on a CPU: a team has nothing to share.
CPU_CODEGEN = {"cpp.vec_isa_ok": True, "cpp.threads": 1}
INDUCTOR_OPTIONS = {**CPU_CODEGEN, "cpp_wrapper": True}
# An AOTInductor package is C++ throughout. A kernel is a few hundred flops on small tensors, so what a call costs is
# its bookkeeping: a tensor per buffer and an ATen call per small matmul. The small matmuls are decomposed into the
# fused kernel (inductor's own pass: on a CPU it applies to a batch of one, physx_cpu's N). Where the buffers live is
# each kernel's choice (docs/performance.md, hot loops at N = 1):
# - on the heap (the default): every call returns fresh output tensors, allocated in C++. For the once-per-control-step
#   kernels, whose outputs are many and all kept (the shared signals return 32), this is 2-2.5x cheaper than the stack
#   and a copy of each output from Python (31 against 48 us for the signals, 3.3 against 8.4 for the pick evaluator);
# - on the stack (`stack_allocation=True`): the intermediates cost nothing to allocate, but the package hands out the
#   same output buffers at every call, so they are copied (`_owned`; `hands_out_again` finds such a package). For the
#   240 Hz flight step, three outputs and many intermediates, this is 2x cheaper (6 against 13.5 us).
# The minimal array-ref interface, which goes with stack allocation in inductor's examples, kept every call's inputs
# alive through the Python runner (30 MB per 100k calls); tests/envs/control/test_fused.py and tests/accel/test_kernels.py
# check that a call leaves nothing behind and that outputs do not alias.
AOT_INDUCTOR_OPTIONS = {
    **CPU_CODEGEN,
    "post_grad_fusion_options": {"decompose_mm_pass": {}},
}
STACK_ALLOCATION = {"aot_inductor.allow_stack_allocation": True}


def _switched_on(variable: str) -> bool:
    return os.environ.get(variable, "1").strip().lower() not in ("0", "false", "no", "off")


def compile_requested() -> bool:
    return _switched_on("AEROBENCH_COMPILE")


def direct_call_requested() -> bool:
    """`AEROBENCH_DIRECT_CALL=0` keeps every package behind its runner (the same numbers, a slower call)."""
    return _switched_on("AEROBENCH_DIRECT_CALL")


def cache_dir() -> Path:
    """Where compiled artifacts are kept across processes: `$AEROBENCH_CACHE_DIR`, else `~/.cache/aerobench`."""
    root = os.environ.get("AEROBENCH_CACHE_DIR")
    return Path(root) if root else Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "aerobench"


def source_digest(files: Sequence[Path]) -> str:
    """The source of every module a kernel chains: a changed law is a new package, never a stale one."""
    h = hashlib.sha256()
    for f in sorted(files):
        h.update(f.name.encode() + f.read_bytes())
    return h.hexdigest()


class _Exported(torch.nn.Module):
    def __init__(self, fn: Callable):
        super().__init__()
        self.fn = fn

    def forward(self, *tensors: torch.Tensor) -> tuple[torch.Tensor, ...]:
        return tuple(self.fn(*tensors))


class Package(NamedTuple):
    """A loaded ahead-of-time package: `run`, the runner's entry (the flat list of inputs -> the flat list of
    outputs), and where asked for, `direct`: its kernel called without the runner (`direct_call`: the inputs as
    arguments, results written into them), or why it cannot be (the exception)."""

    run: Callable[[list[torch.Tensor]], list[torch.Tensor]]
    direct: Callable[..., None] | Exception | None = None


def load_aot(fn: Callable, tensors: Sequence[torch.Tensor], key: str, folder: str,
             dynamic: dict[int, int] | None = None, stack_allocation: bool = False, direct: bool = False) -> Package:
    """`fn` compiled ahead of time for the shapes of `tensors` (CPU), built once per key and loaded from the cache.
    `dynamic` maps an input's position to the dimension left free (e.g. a scene's box count); `stack_allocation`:
    intermediates on the stack, and the same output buffers at every call (see `AOT_INDUCTOR_OPTIONS`); `direct`:
    also the package's kernel as a direct call, for a function that writes its results into its inputs."""
    with trusted_vector_isa():
        return _load_aot(fn, tensors, key, folder, dynamic, stack_allocation, direct)


@contextmanager
def trusted_vector_isa() -> Iterator[None]:
    """Inductor's vector ISA taken from what the CPU advertises, without the probes `cpp.vec_isa_ok` leaves.

    Inductor proves an ISA by building a test library and loading it in a fresh Python process that imports torch.
    `cpp.vec_isa_ok` skips that for the base ISAs (AVX2, AVX-512), but not for the extensions probed wherever the
    CPU advertises them (AVX-512 VNNI and BF16, AMX): three fresh processes on this machine, about 5 s at the first
    package of every process (loading checks the package against the CPU, and the direct entry's build asks
    again), half of an env's start (docs/performance.md; pytorch/pytorch#100378). Inside this context a probe is
    answered without the build: VNNI and BF16 pass, as the probe passes them with any compiler from gcc 10, so the
    ISA, the flags and the cache keys are what the probes gave; AMX is declined (its FP16 flag needs gcc 13, and
    these float32 kernels of a batch of one use no tiles). Inductor keeps the answers for the rest of the process.
    Torch internals: where they are not as expected, the probes run as before."""
    try:
        from torch._inductor.cpu_vec_isa import VecISA

        probe = VecISA.__dict__["check_build"]
    except (ImportError, KeyError):
        yield
        return
    VecISA.check_build = _answered
    try:
        yield
    finally:
        VecISA.check_build = probe


def _answered(isa, code: str) -> bool:
    """`VecISA.check_build` inside `trusted_vector_isa`: an extension the CPU advertises passes, AMX excepted (the
    probe's flags say which it is: `-mamx-*`)."""
    return "-mamx" not in getattr(isa, "_arch_flags", "-mamx")


def _load_aot(fn: Callable, tensors: Sequence[torch.Tensor], key: str, folder: str, dynamic: dict[int, int] | None,
              stack_allocation: bool, direct: bool) -> Package:
    dynamic = dynamic or {}
    options = {**AOT_INDUCTOR_OPTIONS, **(STACK_ALLOCATION if stack_allocation else {})}
    shapes = [tuple("*" if dynamic.get(i) == d else s for d, s in enumerate(t.shape)) for i, t in enumerate(tensors)]
    digest = hashlib.sha256(repr((
        key, shapes, [str(t.dtype) for t in tensors], torch.__version__, torch.backends.cpu.get_cpu_capability(),
        options, "wrapper chosen per build",  # (packages built before `_cpu_wrapper` may not be what they say)
    )).encode()).hexdigest()[:24]
    path = cache_dir() / folder / f"{digest}.pt2"
    if not path.is_file():
        with _one_build_at_a_time():
            if not path.is_file():  # another process may have built it while this one waited
                _build(fn, tensors, dynamic, options, stack_allocation, path)
    # Loading checks the package against the CPU's vector ISA; trust the advertised one here too (the key has it;
    # `trusted_vector_isa` covers the probes that `cpp.vec_isa_ok` leaves).
    before = _mapped_libraries()
    with torch._inductor.config.patch(options):
        run = torch._inductor.aoti_load_package(str(path)).loader.run
    loaded = _mapped_libraries() - before
    entry = None
    if direct:
        try:
            if len(loaded) != 1:
                raise UnsupportedPackage("the package's library was not found among the mapped ones")
            entry = direct_entry(path, Path(next(iter(loaded))), [t.dtype for t in tensors], options)
        except Exception as exc:  # noqa: BLE001 - the runner is the same kernel
            entry = exc
    _remove_extractions(loaded)
    return Package(run, entry)


def _build(fn: Callable, tensors: Sequence[torch.Tensor], dynamic: dict[int, int], options: dict,
           stack_allocation: bool, path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(suffix=".pt2", dir=path.parent)
    os.close(fd)
    try:  # built beside its final name and renamed: a concurrent reader sees a whole package or none
        free = {i: torch.export.Dim(f"dim{i}_{d}", min=1) for i, d in dynamic.items()}
        dynamic_shapes = (tuple({dynamic[i]: free[i]} if i in free else None for i in range(len(tensors))),)
        with warnings.catch_warnings(), _cpu_wrapper(stack_allocation):
            warnings.simplefilter("ignore", FutureWarning)  # torch's own pytree notes, nothing to act on
            program = torch.export.export(_Exported(fn), tuple(tensors), strict=False,
                                          dynamic_shapes=dynamic_shapes if dynamic else None)
            torch._inductor.aoti_compile_and_package(program, package_path=tmp, inductor_configs=dict(options))
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


BUILD_LOCK = "aerobench_aot_build.lock"


@contextmanager
def _one_build_at_a_time() -> Iterator[None]:
    """Ahead-of-time builds one at a time across processes. AOTInductor writes a build's files into inductor's cache
    folder under a name taken from the generated code, without a lock, then zips them: two processes building the
    same graph at once (K workers starting on a fresh cache, or two keys for one function) wrote the same files,
    and one zipped a file the other had just truncated (a package whose metadata was empty, which failed to load).
    The lock lives in that shared folder; a process that waited finds the package built and loads it."""
    try:
        from torch._inductor.runtime.cache_dir_utils import cache_dir as inductor_cache_dir

        folder = Path(inductor_cache_dir())
    except ImportError:
        folder = cache_dir()
    folder.mkdir(parents=True, exist_ok=True)
    with exclusive(folder / BUILD_LOCK):
        yield


_PROC_MAPS = Path("/proc/self/maps")


def _mapped_libraries() -> set[str]:
    """The shared libraries this process has mapped (Linux; elsewhere none are found)."""
    try:
        return {line.split()[-1] for line in _PROC_MAPS.read_text().splitlines() if line.endswith(".so")}
    except OSError:
        return set()


def _remove_extractions(libraries: set[str]) -> None:
    """Loading a package extracts it to a fresh `<tmp>/XXXXXX` folder that torch never removes: 0.7 MB per kernel
    and process, which every worker of every job left behind. Once loaded, the library is mapped and its files are
    not read again: the folders of `libraries` (this load's, `<tmp>/XXXXXX/<build>/data/aotinductor/model/*.so`)
    go."""
    for library in libraries:
        parts = Path(library).parts
        if len(parts) >= 7 and parts[-4:-1] == ("data", "aotinductor", "model"):
            folder = Path(*parts[:-5])
            if folder.parent == Path(tempfile.gettempdir()) or folder.parent == Path("/tmp"):
                shutil.rmtree(folder, ignore_errors=True)


@contextmanager
def _cpu_wrapper(stack_allocation: bool) -> Iterator[None]:
    """Build with the CPU wrapper class that goes with `stack_allocation`. Inductor registers that class once per
    process, by the option of the first build, and every later build in the process used it whatever it asked for
    (a stack build after a heap one came out on the heap, 2x slower a call); here each build gets its own. Torch
    internals: where they are not as expected, the build goes ahead as registered (`hands_out_again` still finds
    what the package does)."""
    try:
        from torch._inductor.codegen import common
        from torch._inductor.codegen.cpp_wrapper_cpu import CppWrapperCpu
        from torch._inductor.codegen.cpp_wrapper_cpu_array_ref import CppWrapperCpuArrayRef

        common.init_backend_registration()
        entry = common.device_codegens["cpu"]
        saved = entry.cpp_wrapper_codegen
    except (ImportError, AttributeError, KeyError):
        yield
        return
    entry.cpp_wrapper_codegen = CppWrapperCpuArrayRef if stack_allocation else CppWrapperCpu
    try:
        yield
    finally:
        entry.cpp_wrapper_codegen = saved


_size, _is_contiguous = torch.Tensor.size, torch.Tensor.is_contiguous


def all_contiguous(tensors: Sequence[torch.Tensor]) -> bool:
    """Whether a package can read `tensors` as they are (it reads raw memory)."""
    return all(map(_is_contiguous, tensors))


def _contiguous(tensors: Sequence[torch.Tensor]) -> list[torch.Tensor]:
    """The inputs as a package reads them: a contiguous copy of any strided one."""
    return list(tensors) if all_contiguous(tensors) else [t.contiguous() for t in tensors]


def _owned(outputs: Sequence[torch.Tensor]) -> list[torch.Tensor]:
    """A package with stack-allocated intermediates returns the same output buffers at every call: copies, so that
    memory fed back (and anything a caller keeps) is not overwritten by the next call (about a microsecond each)."""
    return [t.clone() for t in outputs]


def _as_is(outputs: Sequence[torch.Tensor]) -> Sequence[torch.Tensor]:
    """A package with heap buffers returns fresh outputs at every call (an output that is a view of an input shares
    that input's memory, as the eager function's does)."""
    return outputs


def hands_out_again(run: Callable, inputs: list[torch.Tensor]) -> bool:
    """Whether the package `run` returns an output in the same memory at two calls, a view of an input aside: then
    its outputs are copied (`_owned`). Stack allocation does this; found by calling it, not taken from the option
    asked for, which a build once ignored (`_cpu_wrapper`)."""
    inputs = [t.clone() for t in inputs]  # a package may write into its inputs (a controller's memory)
    own = {t.untyped_storage().data_ptr() for t in inputs}
    first, second = run(inputs), run(inputs)
    return any(a.untyped_storage().data_ptr() == b.untyped_storage().data_ptr()
               and a.untyped_storage().data_ptr() not in own for a, b in zip(first, second))


def _same(a: torch.Tensor, b: torch.Tensor) -> bool:
    """The same values to the bit, a NaN where the other has one."""
    if not a.is_floating_point():
        return torch.equal(a, b)
    return torch.allclose(a, b, rtol=0.0, atol=0.0, equal_nan=True)


class Kernel:
    """`fn` (flat tensors in, a flat tuple of tensors out) as one call: compiled on its first call (ahead of time on
    a CPU, else `torch.compile`); on any compiler failure the next option, reported once. `backend` says which ran
    last: "compiled ahead of time", "compiled", "eager" (asked for) or "eager (fallback: <reason>)".

    `name` says what the kernel is in reports and names its cache folder; `key` is whatever else fixes `fn` besides
    the source of `sources` (bound parameters, constants); `shape_key` picks from the inputs what fixes every input
    shape (default: all of them) and `dynamic` which dimensions stay free in an ahead-of-time package;
    `stack_allocation` keeps an ahead-of-time package's intermediates on the stack (`AOT_INDUCTOR_OPTIONS`)."""

    _reported: set[tuple[str, str]] = set()

    def __init__(self, fn: Callable, name: str, key: object, sources: Sequence[Path], device: torch.device | str,
                 compile: bool, dynamic: dict[int, int] | None = None,
                 shape_key: Callable[[tuple[torch.Tensor, ...]], object] | None = None, stack_allocation: bool = False,
                 direct: bool = False):
        self.fn, self.name, self.dynamic = fn, name, dynamic
        self.stack_allocation, self.direct = stack_allocation, direct and direct_call_requested()
        self._direct: dict[object, Callable[..., None]] = {}  # per shape key: the package's kernel called directly
        self._key, self._sources = key, tuple(sources)
        self._shape_key = shape_key or self._free_shapes
        self.backend = "not run yet" if compile else "eager"
        self._compile = compile
        self._mode = os.environ.get("AEROBENCH_COMPILE_MODE") or None
        self.cuda_graphs = compile and self._mode is not None and "reduce-overhead" in self._mode and str(device).startswith("cuda")
        self._compiled: Callable | None = None  # torch.compile's function
        self._compile_failed = False
        # per shape key: the loaded package, and what its outputs go through (`_owned` or `_as_is`)
        self._aot: dict[object, tuple[Callable, Callable]] = {}
        self.aot_ok = compile and str(device) == "cpu" and self._mode is None
        # the package for the shapes seen last: (its shape key, the package, the sizes of the call that found it,
        # what its outputs go through)
        self._fast: tuple[object, Callable, tuple, Callable] | None = None

    def _free_shapes(self, tensors: tuple[torch.Tensor, ...]) -> tuple:
        """The input shapes, a free dimension left out: one package (loaded once) serves every size of it."""
        free = self.dynamic or {}
        return tuple(tuple(t.shape) if i not in free else tuple(t.shape[:free[i]]) + tuple(t.shape[free[i] + 1:])
                     for i, t in enumerate(tensors))

    def __call__(self, *tensors: torch.Tensor) -> tuple[torch.Tensor, ...] | list[torch.Tensor]:
        if not self._compile:
            return self.fn(*tensors)
        fast = self._fast
        if fast is not None and fast[2] == tuple(map(_size, tensors)):  # the very sizes of the last call's package
            self.backend = "compiled ahead of time"
            return fast[3](fast[1](_contiguous(tensors)))
        if self.aot_ok:
            shapes = self._shape_key(tensors)  # another size of a free dimension finds the same package
            loaded = self._aot.get(shapes)
            if loaded is None:
                try:
                    key = repr((source_digest(self._sources), self._key))
                    inputs = [t.contiguous() for t in tensors]
                    run, entry = load_aot(self.fn, inputs, key, self.name, self.dynamic, self.stack_allocation,
                                          self.direct)
                    loaded = self._aot[shapes] = (run, _owned if hands_out_again(run, inputs) else _as_is)
                    if self.direct:
                        self._keep_direct(shapes, run, entry, inputs)
                except Exception as exc:  # noqa: BLE001 - torch.compile (or eager) is the same function
                    self.aot_ok = False
                    self._report("ahead-of-time compilation", exc, "running torch.compile instead")
            if loaded is not None:
                run, outputs = loaded
                self._fast = (shapes, run, tuple(map(_size, tensors)), outputs)
                self.backend = "compiled ahead of time"
                return outputs(run(_contiguous(tensors)))
        compiled = self._compiled_fn()
        if compiled is None:
            return self.fn(*tensors)
        if self.cuda_graphs:  # a captured graph reuses its output buffers at the next replay: keep copies
            torch.compiler.cudagraph_mark_step_begin()
        try:
            result = compiled(*tensors)
        except Exception as exc:  # noqa: BLE001
            self._fall_back(exc)
            return self.fn(*tensors)
        self.backend = "compiled"
        return tuple(t.clone() for t in result) if self.cuda_graphs else result

    def package(self, *tensors: torch.Tensor) -> Callable | None:
        """The ahead-of-time package this kernel ran last, if it was for inputs shaped like `tensors`; else None. It
        takes the flat list of inputs, which must be contiguous, and returns its outputs as they are: with stack
        allocation, the package's own output buffers, which its next call overwrites. For a hot loop that
        checks contiguity itself and copies what it keeps: a small kernel's call through `__call__` is mostly those
        checks and copies."""
        fast = self._fast
        return fast[1] if self._compile and fast is not None and fast[0] == self._shape_key(tensors) else None

    def direct_call(self, *tensors: torch.Tensor) -> Callable[..., None] | None:
        """Where this kernel was made with `direct` and its package for inputs shaped like `tensors` allows it: the
        package's kernel as a function of the inputs (as arguments, contiguous, of those shapes and dtypes, which it
        does not check) that writes its results into them (`direct_call`); else None. For the hot loop that
        `package` serves, without the runner's cost per call."""
        return self._direct.get(self._shape_key(tensors)) if self.package(*tensors) is not None else None

    def _keep_direct(self, shapes: object, run: Callable, entry: Callable | Exception | None,
                     inputs: list[torch.Tensor]) -> None:
        """Keep the direct entry if it writes what the runner writes, to the bit (it is the same generated kernel,
        compiled apart from its package), on the first inputs and on a perturbed copy of them; else report why."""
        if not callable(entry):
            self._report("direct call", entry or UnsupportedPackage("no entry"), "calling the package's runner")
            return
        noise = torch.Generator().manual_seed(0)  # its own: the process's random state stays the caller's
        perturbed = [t + 0.01 * torch.randn(t.shape, generator=noise, dtype=t.dtype) if t.is_floating_point() else t
                     for t in inputs]
        try:  # a failing entry costs the direct call, never the package it was made from
            for trial in (inputs, perturbed):
                by_runner, by_entry = [t.clone() for t in trial], [t.clone() for t in trial]
                run(by_runner)
                entry(*by_entry)
                if not all(map(_same, by_runner, by_entry)):
                    raise UnsupportedPackage("its results differ from the runner's")
        except Exception as exc:  # noqa: BLE001 - the runner is the same kernel
            self._report("direct call", exc, "calling the package's runner")
            return
        self._direct[shapes] = entry

    def _compiled_fn(self) -> Callable | None:
        if not self._compile or self._compile_failed:
            return None
        if self._compiled is None:
            try:
                self._compiled = torch.compile(self.fn, dynamic=False, fullgraph=True, mode=self._mode,
                                               options=INDUCTOR_OPTIONS)
            except Exception as exc:  # noqa: BLE001 - e.g. no compiler backend: the eager function is the same
                self._fall_back(exc)
        return self._compiled

    def _fall_back(self, exc: Exception) -> None:
        reason = self._report("torch.compile", exc, "running the eager function (same numbers, slower on CPU)")
        self.backend, self._compiled, self._compile_failed = f"eager (fallback: {reason})", None, True

    def _report(self, what: str, exc: Exception, instead: str) -> str:
        first_line = str(exc).splitlines()[0] if str(exc) else ""
        reason = f"{type(exc).__name__}: {first_line}"[:200]
        if (self.name, what, reason) not in Kernel._reported:
            Kernel._reported.add((self.name, what, reason))
            log.warning("aerobench: %s of the %s failed (%s); %s. AEROBENCH_COMPILE=0 skips the attempt.",
                        what, self.name.replace("_", " "), reason, instead)
        return reason


_SHARED: dict[tuple, Kernel] = {}


def shared_kernel(fn: Callable, name: str, key: object, sources: Sequence[Path], device: torch.device | str,
                  compile: bool | None = None, **options) -> Kernel:
    """The process's one `Kernel` of `name` for `key` on `device` (`compile`: `AEROBENCH_COMPILE` unless given),
    made on the first request and shared by every env, evaluator or expert that asks again, so it compiles once per
    process. `key` must fix `fn` (the bound law or constants); `options` go to `Kernel`."""
    compile = compile_requested() if compile is None else compile
    index = (name, key, str(device), compile)
    if index not in _SHARED:
        _SHARED[index] = Kernel(fn, name, key, sources, device, compile, **options)
    return _SHARED[index]
