"""`bench/attitude_modes.py`: the linear attitude loop's mode from the platform's mass properties, checked against a
hand computation, the parallel-axis effect of a held object, and the PSD peak finder on a known spectrum."""

import math
import sys
from pathlib import Path

BENCH = Path(__file__).resolve().parents[2] / "bench"
sys.path.insert(0, str(BENCH))

import attitude_modes as am  # noqa: E402

from aerobench.envs.objects import OBJECTS  # noqa: E402
from aerobench.envs.platforms import GRIPPER_PLATFORM  # noqa: E402


def test_attitude_mode_is_the_second_order_systems():
    mode = am.attitude_mode(0.04, 2.5, 0.55)
    assert math.isclose(mode["natural_hz"], math.sqrt(2.5 / 0.04) / (2 * math.pi))
    assert math.isclose(mode["damping_ratio"], 0.55 / (2 * math.sqrt(2.5 * 0.04)))
    # the tilt-rate response s / (J s^2 + k_w s + k_R) at s = j w_n has magnitude 1 / k_w
    w = 2 * math.pi * mode["natural_hz"]
    assert math.isclose(abs(1j * w / (0.04 * (1j * w) ** 2 + 0.55 * 1j * w + 2.5)) ** 2, mode["peak_gain_sq"])


def test_a_held_object_adds_its_parallel_axis_inertia_and_lowers_the_mode():
    bare = am.roll_pitch_inertia(GRIPPER_PLATFORM, None)
    can = OBJECTS["master_chef_can"]
    held = am.roll_pitch_inertia(GRIPPER_PLATFORM, can)
    # a point mass m at depth d below a body of mass M adds m M d^2 / (m + M) about the joint centre of mass (+ a
    # little for the shift of the rest): at least the object's mass times 0.2 m squared, scaled by M / (m + M)
    assert held - bare > can.mass_kg * 0.2**2 * 2.38 / (2.38 + can.mass_kg)
    rows = {r["load"]: r for r in am.modes()}
    assert rows["unloaded"]["nominal"]["natural_hz"] > rows["master_chef_can"]["nominal"]["natural_hz"]
    # the payload-aware gains move the mode up by sqrt(12 / 2.5) for the same load
    ratio = rows["master_chef_can"]["payload-aware"]["natural_hz"] / rows["master_chef_can"]["nominal"]["natural_hz"]
    assert math.isclose(ratio, math.sqrt(12 / 2.5))


def test_psd_local_maxima_finds_the_bumps_inside_the_band():
    freq = [0.1 * i for i in range(60)]
    psd = [math.exp(-((f - 1.4) / 0.2) ** 2) + 0.1 * math.exp(-((f - 3.0) / 0.2) ** 2) + (5.0 if i == 1 else 0.0)
           for i, f in enumerate(freq)]
    peaks = am.psd_local_maxima(freq, psd)
    assert [round(p["freq_hz"], 1) for p in peaks] == [1.4, 3.0]  # the 0.1 Hz spike is below the band
