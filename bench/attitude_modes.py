"""Where the payload ablation's tilt-rate spectrum peaks, from the attitude loop's physics.

The attitude law (spec Eq. att) `tau = -k_R e_R - k_w (omega - omega_des)` on a rigid body of roll/pitch inertia J is,
for small tilts, the second-order system `J theta'' + k_w theta' + k_R theta = tau_dist`. A disturbance torque reaches
the tilt *rate* through `H(s) = s / (J s^2 + k_w s + k_R)`, whose gain peaks at the natural frequency
`f_n = sqrt(k_R / J) / 2 pi` with height `1 / k_w` for any damping `zeta = k_w / (2 sqrt(k_R J))`. So the gains set
where a carry's tilt-rate PSD can peak, and how far a given disturbance is amplified there; the object in the jaws
adds inertia (a rigid grasp: its mass at the tool centre point, 0.28 m below the airframe) and lowers `f_n`.

This script computes `f_n`, `zeta` and `|H|^2` at the peak for the gripper platform, unloaded and holding each
TidyHouse class, with the nominal gains (2.5, 0.55) and the payload-aware ones (12, 1.2), from the platform's own
mass properties (`platforms.py`, the same composite the simulator builds); then it lists the local maxima of the
committed ablation's median PSDs (docs/results/payload_ablation/payload_ablation.json) beside them.

    python bench/attitude_modes.py [--ablation docs/results/payload_ablation/payload_ablation.json] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np
import transforms3d

from aerobench.envs.agents.airframe import composite_mass_properties
from aerobench.envs.objects import OBJECTS, ObjectSpec
from aerobench.envs.platforms import GRIPPER_PALM_Z_M, GRIPPER_PLATFORM, Component, PlatformSpec

ABLATION_JSON = Path("docs/results/payload_ablation/payload_ablation.json")
BAND_HZ = (0.5, 5.0)  # below: the transport's own manoeuvres; above: nothing of the loop's


def gain_sets(platform: PlatformSpec) -> dict[str, tuple[float, float]]:
    g = platform.gains
    return {"nominal": (g.k_R, g.k_w), "payload-aware": (g.payload_k_R, g.payload_k_w)}


def rigid_parts(platform: PlatformSpec, obj: ObjectSpec | None) -> tuple[Component, ...]:
    """The airframe's components, the two fingers (their own links, rigid while closed) and a held object whose
    centre of mass sits where a planned grasp puts it: `grasp_point_m` of the object at the tool centre point."""
    g, tcp = platform.gripper, np.asarray(platform.grasp_point_m)
    finger_z = GRIPPER_PALM_Z_M - g.finger_length_m / 2  # the fingers hang from the palm
    parts = list(platform.airframe_components) + [
        Component(f"finger_{s}", g.finger_mass_kg, (0.0, s * 0.02, finger_z)) for s in (-1, 1)
    ]
    if obj is not None:
        com_in_object = np.array([0.0, 0.0, obj.height_m / 2])  # uniform solid (the bowl: its centre line)
        parts.append(Component("object", obj.mass_kg, tuple(tcp + com_in_object - np.asarray(obj.grasp_point_m))))
    return tuple(parts)


def roll_pitch_inertia(platform: PlatformSpec, obj: ObjectSpec | None) -> float:
    """The smaller of the roll and pitch moments about the composite centre of mass (kg m^2); with a heavy object
    below the airframe they exceed the yaw moment, so they are read off the tensor, not the smallest principal."""
    _, _, principal, quat = composite_mass_properties(rigid_parts(platform, obj), platform.airframe_inertia_kgm2)
    axes = transforms3d.quaternions.quat2mat(quat)
    tensor = axes @ np.diag(principal) @ axes.T
    return float(min(tensor[0, 0], tensor[1, 1]))


def attitude_mode(inertia: float, k_R: float, k_w: float) -> dict[str, float]:
    return {
        "natural_hz": math.sqrt(k_R / inertia) / (2 * math.pi),
        "damping_ratio": k_w / (2 * math.sqrt(k_R * inertia)),
        "peak_gain_sq": 1.0 / k_w**2,  # |H|^2 at f_n, (rad/s per N m)^2
    }


def modes(platform: PlatformSpec = GRIPPER_PLATFORM) -> list[dict]:
    rows = []
    for name, obj in [("unloaded", None)] + sorted(OBJECTS.items(), key=lambda kv: kv[1].mass_kg):
        inertia = roll_pitch_inertia(platform, obj)
        row = {"load": name, "mass_kg": obj.mass_kg if obj else 0.0, "inertia_kgm2": inertia}
        row.update({cond: attitude_mode(inertia, *gains) for cond, gains in gain_sets(platform).items()})
        rows.append(row)
    return rows


def psd_local_maxima(freq: list[float], median: list[float], band: tuple[float, float] = BAND_HZ) -> list[dict]:
    """Bins inside `band` above both neighbours."""
    return [
        {"freq_hz": freq[i], "psd": median[i]}
        for i in range(1, len(freq) - 1)
        if band[0] <= freq[i] <= band[1] and median[i] > median[i - 1] and median[i] > median[i + 1]
    ]


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ablation", type=Path, default=ABLATION_JSON, help="a payload_ablation.py JSON with a PSD")
    parser.add_argument("--json", type=Path, default=None, help="also write the table here")
    args = parser.parse_args(argv)

    rows = modes()
    print("attitude loop of the gripper platform (rigid grasp), per load: f_n Hz / zeta / |H|^2 at f_n")
    print(f"{'load':24s} {'kg':>5s} {'J kg m^2':>9s}   {'nominal (2.5, 0.55)':>22s}   {'payload-aware (12, 1.2)':>24s}")
    for r in rows:
        n, a = r["nominal"], r["payload-aware"]
        print(f"{r['load']:24s} {r['mass_kg']:5.3f} {r['inertia_kgm2']:9.4f}   "
              f"{n['natural_hz']:5.2f} / {n['damping_ratio']:4.2f} / {n['peak_gain_sq']:4.2f}      "
              f"{a['natural_hz']:5.2f} / {a['damping_ratio']:4.2f} / {a['peak_gain_sq']:4.2f}")
    out = {"modes": rows}
    if args.ablation.exists():
        psd = json.loads(args.ablation.read_text())["psd"]
        out["psd_local_maxima"] = {}
        for cond in ("nominal", "payload-aware"):
            peaks = psd_local_maxima(psd[cond]["freq_hz"], psd[cond]["median"])
            out["psd_local_maxima"][cond] = peaks
            listed = ", ".join(f"{p['freq_hz']:.2f} Hz ({p['psd']:.3g})" for p in peaks)
            print(f"median tilt-rate PSD, {cond}: local maxima in {BAND_HZ[0]}-{BAND_HZ[1]} Hz: {listed}  [(deg/s)^2/Hz]")
    else:
        print(f"no ablation JSON at {args.ablation}: run bench/payload_ablation.py first (PSD peaks not listed)")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
