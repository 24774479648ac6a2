"""CPU acceleration behind one small interface: a pure function of tensors run as one compiled call.

`Kernel(fn, ...)` / `shared_kernel(fn, ...)` run `fn` compiled (AOTInductor ahead of time on a CPU, `torch.compile`
elsewhere) with the eager function as the fallback that gives the same numbers; `AEROBENCH_COMPILE=0` is the off
switch (eager everywhere), `AEROBENCH_DIRECT_CALL=0` keeps the package's own runner for the in-place flight step
(`direct_call`). The builds use torch's public export and AOTInductor APIs; two scoped hooks on inductor internals
(`trusted_vector_isa`, `_cpu_wrapper`: restored on exit, skipped where torch's internals differ) and `direct_call`
(which reads the generated wrapper) live here and nowhere else, each measured in docs/performance.md. Nothing here has
a process-global side effect at import.

Below the envs: imports nothing of aerobench but `file_lock`; the envs and the expert call it, never the reverse.
"""

from .kernels import Kernel, all_contiguous, compile_requested, direct_call_requested, shared_kernel

__all__ = ["Kernel", "all_contiguous", "compile_requested", "direct_call_requested", "shared_kernel"]
