"""Tiny, randomly initialised pi0 / pi0.5 as LeRobot policy types `pi0_tiny` and `pi05_tiny`.

LeRobot's pi0 / pi0.5 come in two hard-coded sizes (PaliGemma 2B + a 300M expert, about 4B parameters with SigLIP).
These types subclass LeRobot's own configs and policies and only shrink the widths, depths and the vision tower, so
the whole pi0 / pi0.5 code path (processors, flow matching, action chunks) runs on a CPU in tests. They follow
LeRobot's plugin conventions (`configuration_*` / `modeling_*` / `processor_*` modules, `<X>Config` -> `<X>Policy`),
so `lerobot-train` and `lerobot-eval` find them once this package is imported, which the `lerobot_env_aerobench`
plugin distribution does. Importing this package registers the two config types.
"""

from .configuration_pi_tiny import PI0TinyConfig, PI05TinyConfig

__all__ = ["PI0TinyConfig", "PI05TinyConfig"]
