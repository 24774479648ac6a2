"""`kernels.shared_kernel`: one kernel per process for each name, key, device and compile setting."""

import torch

from aerobench.envs.kernels import shared_kernel


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
