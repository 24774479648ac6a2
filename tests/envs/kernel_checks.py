"""The check every compiled kernel gets: ahead of time on a CPU, it gives the eager function's outputs."""

from collections.abc import Callable, Sequence

import torch

from aerobench.accel.kernels import Kernel


def assert_compiled_is_eager(fn: Callable, name: str, key: object, tensors: Sequence[torch.Tensor],
                             fields: Sequence[str], rtol: float = 1e-5, atol: float = 1e-5) -> tuple:
    """Compile `fn` (flat tensors in, a flat tuple out) ahead of time as `Kernel(name, key)`, run it and `fn` on
    `tensors`, assert it ran compiled and that each output (named by `fields`) agrees; return the eager outputs."""
    kernel = Kernel(fn, name, key, [], "cpu", compile=True)
    compiled, eager = kernel(*tensors), fn(*tensors)
    assert kernel.backend == "compiled ahead of time", kernel.backend
    assert len(compiled) == len(eager) == len(fields)
    for field, a, b in zip(fields, compiled, eager):
        torch.testing.assert_close(a, b, rtol=rtol, atol=atol, msg=field)
    return tuple(eager)
