"""The evaluation conditions' physical constants, each with its source (the conditions' one place for numbers).

They live here and not in `platforms.py`: the compiled physics step is keyed by the source of `platforms.py` and
`control/` (`control.fused._control_sources`), and none of these numbers enters that step, so changing one must not
rebuild it. Platform constants (rotor radius and positions, maximum thrust, mass) are read from `platforms.py`.

Where a number is aerobench's choice rather than a measured value, it says so.
"""

from __future__ import annotations

# --------------------------------------------------------------------------------------------------------------------
# Air and airframe drag
# --------------------------------------------------------------------------------------------------------------------
AIR_DENSITY_KGPM3 = 1.225  # ICAO Standard Atmosphere (Doc 7488), sea level, 15 C
# Rotor drag, the force linear in the air-relative velocity in the rotor plane (blade flapping and induced drag):
# F = -m R diag(d_xy, d_xy, d_z) R^T v_rel, Faessler, Franchi & Scaramuzza, "Differential flatness of quadrotor
# dynamics subject to rotor drag", IEEE RA-L 3(2), 2018, identify mass-normalised coefficients of a few tenths per
# second for their quadrotor; the X500's own are not published, so 0.4 is aerobench's assumption.
ROTOR_DRAG_XY_PER_S = 0.4
ROTOR_DRAG_Z_PER_S = 0.0
# Parasitic (pressure) drag of the frame, F = -1/2 rho C_D A |v_rel| v_rel: C_D A of the X500's frame, arms, battery
# and payload seen edge-on, about 0.05 m^2 of a bluff body with C_D ~ 1 (Hoerner, "Fluid-Dynamic Drag", 1965, for
# flat plates and boxes); aerobench's estimate, not a wind-tunnel figure.
PARASITIC_DRAG_AREA_M2 = 0.05

# --------------------------------------------------------------------------------------------------------------------
# Turbulence: the Dryden model's low-altitude form (MIL-F-8785C, 1980, Sec. 3.7.2; MIL-HDBK-1797, 1997)
# --------------------------------------------------------------------------------------------------------------------
FEET_PER_M = 1.0 / 0.3048
DRYDEN_LENGTH_BASE = 0.177  # L_u = L_v = h / (0.177 + 0.000823 h)^1.2 ft, sigma_u / sigma_w = 1 / (...)^0.4 (h in ft)
DRYDEN_LENGTH_SLOPE_PER_FT = 0.000823
DRYDEN_SIGMA_W_PER_W20 = 0.1  # sigma_w = 0.1 W20, W20 the wind speed 20 ft above ground
DRYDEN_LIGHT_W20_MPS = 15.0 * 0.514444  # MIL-F-8785C: light turbulence, W20 = 15 knots
FLIGHT_ALTITUDE_M = 1.5  # the height the length scales are evaluated at: the skills' cruise height (aerobench's)
# The wind rises from calm over the episode's first seconds: a drone starts trimmed in the air it hovers in, and a
# full-strength wind switched on at the first step would be an impulse on an untrimmed controller (the integrator
# starts at zero) that no real flight meets. aerobench's choice.
WIND_ONSET_S = 2.0
WIND_NOISE_HORIZON_STEPS = 2048  # control steps of noise drawn per episode (102 s; longer episodes repeat it)

# --------------------------------------------------------------------------------------------------------------------
# Surfaces near the rotors
# --------------------------------------------------------------------------------------------------------------------
# Ground effect, Cheeseman & Bennett, "The effect of the ground on a helicopter rotor in forward flight", ARC R&M
# 3021, 1955 (hover, method of images): T_IGE / T_OGE = 1 / (1 - (R / 4z)^2). It diverges at z = R/4; below half a
# radius the rotor's distance is held at R/2 (ratio 4/3), the usual validity limit of the image model.
GROUND_EFFECT_MIN_HEIGHT_RADII = 0.5
# Ceiling effect, the form Sanchez-Cuevas, Heredia & Ollero fitted to a rotor under a ceiling ("Multirotor UAS for
# bridge inspection by contact using the ceiling effect", ICUAS 2017): T_ICE / T_OCE = 1 / (1 - (1/k1) (R / (d +
# k2))^2). Their fitted constants are for their rotor; aerobench's k1, k2 (k2 in rotor radii) are its own choice:
# 1.4 at contact, 1.08 one radius below the ceiling, 1.03 two radii below.
CEILING_K1 = 3.5
CEILING_K2_RADII = 1.0
# Near-wall effect: the rotor is drawn towards the wall (suction), more strongly the harder it blows and the closer the
# wall (Yang et al., "Wall Inspector: quadrotor control in wall-proximity through model compensation", arXiv
# 2509.21496, 2025, identify such a suction force from rotor speed and wall distance).
# aerobench's form: per rotor F = c T (R / d)^2 towards the nearest wall face, d held at >= R/2, by analogy with the
# inverse-square image-rotor law above; c = 0.05 (5% of the rotor's thrust with the disk's edge at the wall) is
# aerobench's choice, not a fitted value.
WALL_SUCTION_COEFFICIENT = 0.05
WALL_MIN_DISTANCE_RADII = 0.5
SURFACE_FAR_M = 1e3  # distance reported where no surface is below / above / beside a rotor

# --------------------------------------------------------------------------------------------------------------------
# Motors
# --------------------------------------------------------------------------------------------------------------------
# First-order rotor response of the PX4 X500 Gazebo model (gazebo_motor_model: timeConstantUp / timeConstantDown)
PX4_MOTOR_TIME_CONSTANT_UP_S = 0.0125
PX4_MOTOR_TIME_CONSTANT_DOWN_S = 0.025
SLOW_MOTOR_TIME_CONSTANT_S = 0.1  # a sluggish rotor (8x the X500's spin-up): aerobench's stress level
# Thrust headroom of a sagging battery: motor speed ~ voltage (the no-load KV law), thrust ~ speed^2 (momentum theory),
# so the maximum thrust scales with (V / V_full)^2; a LiPo cell at its nominal 3.7 V instead of a full 4.2 V.
LIPO_FULL_CELL_V = 4.2
LIPO_NOMINAL_CELL_V = 3.7

# --------------------------------------------------------------------------------------------------------------------
# Sensors (the state estimate a policy reads)
# --------------------------------------------------------------------------------------------------------------------
# White noise per control step on an onboard state estimate. aerobench's choice, of the size of a good visual-inertial
# estimate's short-term error (cf. Delmerico & Scaramuzza, "A benchmark comparison of monocular visual-inertial
# odometry algorithms for flying robots", ICRA 2018); not one system's measured figure.
POSITION_NOISE_M = 0.02
ATTITUDE_NOISE_RAD = 0.0175  # 1 degree
VELOCITY_NOISE_MPS = 0.05
ANGULAR_VELOCITY_NOISE_RPS = 0.02
STATE_DELAY_STEPS = 2  # 100 ms at 20 Hz: an estimate from a camera pipeline's latency (aerobench's choice)

# --------------------------------------------------------------------------------------------------------------------
# Payload mismatch: the carried object's real mass against the nominal mass the controller feeds forward
# (spec appendix "Payload-Aware Flight Control": the class's mass is added after three grasped control steps)
# --------------------------------------------------------------------------------------------------------------------
HEAVY_PAYLOAD_SCALE = 1.5
LIGHT_PAYLOAD_SCALE = 0.5

# --------------------------------------------------------------------------------------------------------------------
# What the cameras see (visual conditions, `visual.py`)
# --------------------------------------------------------------------------------------------------------------------
# Lighting. The renderer has no auto-exposure, so a scaled light is a darker or brighter image. The scales are
# aerobench's choice: x0.3 is a room lit for the evening rather than for work (EN 12464-1 asks 500 lx for reading and
# writing; a living room at night has a few hundred lux or less), x2 clips the bright surfaces.
DIM_LIGHT_SCALE = 0.3
BRIGHT_LIGHT_SCALE = 2.0
# A warm-white lamp (2700-3000 K, incandescent and "warm white" LEDs) seen by a camera white-balanced for daylight:
# the light's colour is the Planckian radiator's at WARM_LIGHT_K over that at DAYLIGHT_K, in linear sRGB, at equal
# luminance (`visual.colour_temperature_tint`).
WARM_LIGHT_K = 3000.0
DAYLIGHT_K = 6500.0  # about CIE D65, sRGB's white point
# The Planckian locus in CIE 1931 xy as cubic splines in 1/T and x, Kim et al., "Design of advanced color temperature
# control system for HDTV applications", J. Korean Phys. Soc. 41(6), 2002 (valid 1667-25000 K): x(T) for T up to
# PLANCK_X_SPLIT_K and above it; y(x) for T up to 2222 K, up to 4000 K and above (coefficients of x^3, x^2, x, 1;
# x's of 1e9/T^3, 1e6/T^2, 1e3/T, 1).
PLANCK_X_SPLIT_K = 4000.0
PLANCK_X_LOW = (-0.2661239, -0.2343589, 0.8776956, 0.179910)
PLANCK_X_HIGH = (-3.0258469, 2.1070379, 0.2226347, 0.240390)
PLANCK_Y_SPLITS_K = (2222.0, 4000.0)
PLANCK_Y = ((-1.1063814, -1.34811020, 2.18555832, -0.20219683),
            (-0.9549476, -1.37418593, 2.09137015, -0.16748867),
            (3.0817580, -5.87338670, 3.75112997, -0.37001483))
# CIE XYZ to linear sRGB (IEC 61966-2-1:1999) and the luminance of linear sRGB (its Y row of the inverse, Rec. 709)
XYZ_TO_LINEAR_SRGB = ((3.2406, -1.5372, -0.4986), (-0.9689, 1.8758, 0.0415), (0.0557, -0.2040, 1.0570))
SRGB_LUMINANCE = (0.2126, 0.7152, 0.0722)
# The sun low over the horizon at the layout's own azimuth (nominal layouts draw 35-70 deg): light from the side, as
# through a window late in the day. aerobench's choice.
LOW_SUN_ELEVATION_DEG = 10.0
# Surface colours: each colour of the layout's static boxes times per-channel gains drawn uniformly in [1 - a, 1 + a]
# (a grey wall turns pink or green, a brown floor blue-ish); bounded colour randomisation in the manner of Tobin et
# al., "Domain randomization for transferring deep neural networks from simulation to the real world", IROS 2017.
# a = 0.5 is aerobench's choice.
SURFACE_GAIN_CHANGE = 0.5
# Camera noise. RGB: white Gaussian noise of RGB_NOISE_SIGMA levels (of 255) per pixel and channel: aerobench's choice,
# of the size of a small CMOS camera's temporal noise at mid-grey under indoor light (the Poissonian-Gaussian model of
# Foi et al., IEEE TIP 17(10), 2008, at one signal level); not one camera's measured figure.
RGB_NOISE_SIGMA = 4.0
# Depth: an Intel RealSense D435's stereo depth noise, RMS = z^2 s / (f B) (Grunnet-Jepsen, Sweetser & Woodfill,
# "Tuning depth cameras for best performance", Intel white paper, rev. 2.0: subpixel RMS s ~ 0.08 for a textured
# scene, f = 1/2 X_res / tan(HFOV / 2) at the D435's best resolution 848 x 480; baseline 50 mm and depth HFOV 87 deg
# from the D400 series datasheet): 3.6 mm at 1 m, 14 mm at 2 m, 32 mm at 3 m.
D435_SUBPIXEL_RMS = 0.08
D435_BASELINE_M = 0.050
D435_DEPTH_WIDTH_PX = 848
D435_DEPTH_HFOV_DEG = 87.0
# Motion blur: each frame integrates the scene over an exposure that ends at the frame; half the 50 ms control period
# (the "180-degree shutter" of film cameras: exposure = 1 / (2 x frame rate)), within the 10-33 ms a small camera's
# auto-exposure takes indoors. aerobench's choice.
MOTION_BLUR_EXPOSURE_S = 0.025
MOTION_BLUR_TAPS = 9  # samples along each pixel's path over the exposure (bilinear between pixels)
