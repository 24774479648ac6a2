"""Flight plots: position, tilt, vertical integrator and rotor thrusts over time."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..envs.platforms import PlatformSpec
from .scenarios import Trace


def plot_flight(trace: Trace, platform: PlatformSpec, path: Path, title: str = "") -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(4, 1, figsize=(9, 10), sharex=True)
    for i, name in enumerate("xyz"):
        axes[0].plot(trace.t, trace.position[:, i], label=name)
    if trace.reference_position is not None:
        ref = trace.reference_position - trace.reference_position[0] + trace.position[0]
        for i in range(3):
            axes[0].plot(trace.t, ref[:, i], "--", color="k", lw=0.8, label="free body" if i == 0 else None)
    axes[0].set_ylabel("position [m]")
    axes[0].legend(loc="upper right", ncol=4, fontsize=8)
    axes[1].plot(trace.t, np.degrees(np.arccos(np.clip(trace.tilt_cos, -1, 1))))
    axes[1].set_ylabel("tilt [deg]")
    limit = platform.gains.integral_limit
    axes[2].plot(trace.t, trace.xi[:, 2])
    axes[2].axhline(limit, color="gray", ls=":")
    axes[2].axhline(-limit, color="gray", ls=":")
    axes[2].set_ylabel("xi_z [m/s^2]")
    for i in range(trace.rotor_thrusts.shape[1]):
        axes[3].plot(trace.t, trace.rotor_thrusts[:, i], lw=0.8, label=f"rotor {i}")
    axes[3].axhline(platform.rotors.max_thrust_n, color="gray", ls=":")
    axes[3].set_ylabel("rotor thrust [N]")
    axes[3].set_xlabel("time [s]")
    axes[3].legend(loc="upper right", ncol=4, fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
