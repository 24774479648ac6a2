"""The libraries' start-up noise, quieted in every process aerobench starts (the CLI, evaluation workers): ManiSkill's
warnings (its logger is "mani_skill " with a space), torch's "No CUDA runtime is found" from its C++ extension
loader on a CPU machine, the datasets library's per-file progress bars and FFmpeg's per-video notes. aerobench's own
progress bars and one-line errors say what is going on."""

from __future__ import annotations

import logging
import os
import warnings

NOISY_LOGGERS = ("mani_skill", "mani_skill ", "torch.utils.cpp_extension")


def quiet_libraries() -> None:
    os.environ.setdefault("HF_DATASETS_DISABLE_PROGRESS_BARS", "1")
    # LeRobot's SuppressProgressBars turns the bars back on when it is done, which the variable refuses with a warning
    warnings.filterwarnings("ignore", message="Cannot enable progress bars")
    for name in NOISY_LOGGERS:
        logging.getLogger(name).setLevel(logging.ERROR)
    import av

    av.logging.set_level(av.logging.ERROR)
