"""A detector of host synchronization for the per-step paths that must not make any (CUDA-graph capturable)."""

import torch
from torch.utils._python_dispatch import TorchDispatchMode


class NoHostSync(TorchDispatchMode):
    """Fails on every op that turns a tensor into a Python value (`.item()`, `bool()`, `.any()` in an `if`, ...)."""

    SYNCING = {torch.ops.aten._local_scalar_dense.default, torch.ops.aten.is_nonzero.default,
               torch.ops.aten.equal.default, torch.ops.aten.allclose.default}

    def __torch_dispatch__(self, func, types, args=(), kwargs=None):
        if func in self.SYNCING:
            raise AssertionError(f"host synchronization in a per-step path: {func}")
        return func(*args, **(kwargs or {}))
