"""Fly one scenario on `AeroFly-v1` (physx_cpu) and measure it: the engine behind `aerobench fly` and `make demo`."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch

from ..envs import flight_test  # noqa: F401  (registers AeroFly-v1)
from ..envs.control.payload import ControllerMode
from ..envs.platforms import CONTROL_HZ, MAX_SPEED_MPS, MAX_YAW_RATE_RPS, PHYSICS_HZ, get_platform
from ..video import write_video
from .scenarios import Scenario, Trace, get_scenario

PAYLOAD_OBJECT = "tomato_soup_can"  # the payload's shape; its mass comes from --payload-kg
VIDEO_EVERY_N_CONTROL_STEPS = 2  # 10 fps


@dataclass(frozen=True)
class FlightRequest:
    """What `aerobench fly` was asked to do. Validated in `__post_init__`."""

    platform: str = "gripper"
    scenario: str = "hover"
    seconds: float | None = None
    payload_kg: float | None = None
    controller: str = "payload-aware"
    video: str | None = None
    plot: str | None = None
    seed: int = 0

    def __post_init__(self):
        get_platform(self.platform)
        scenario = get_scenario(self.scenario)
        ControllerMode.parse(self.controller)
        if self.seconds is not None and not (math.isfinite(self.seconds) and self.seconds > 0):
            raise ValueError(f"--seconds must be a positive number, got {self.seconds}")
        if self.payload_kg is not None and not (math.isfinite(self.payload_kg) and 0 <= self.payload_kg <= 1.5):
            raise ValueError(f"--payload-kg must be between 0 and 1.5 kg, got {self.payload_kg}")
        if scenario.reference_body and self.payload_kg:
            raise ValueError("the reference scenario compares bare airframes; drop --payload-kg")


@dataclass
class FlightResult:
    metrics: dict
    trace: Trace
    frames: list[np.ndarray]


def _payload_kg(req: FlightRequest, scenario: Scenario) -> float:
    return scenario.default_payload_kg if req.payload_kg is None else req.payload_kg


def fly(req: FlightRequest) -> FlightResult:
    """Run the scenario closed-loop for its duration (or until it is done) and compute its metrics."""
    scenario = get_scenario(req.scenario)
    platform = get_platform(req.platform)
    payload_kg = _payload_kg(req, scenario)
    seconds = req.seconds if req.seconds is not None else scenario.default_seconds
    env = gym.make(
        "AeroFly-v1",
        obs_mode="state",
        render_mode="rgb_array" if req.video else None,
        scene=scenario.scene,
        platform=req.platform,
        controller=req.controller,
        payload=PAYLOAD_OBJECT if payload_kg > 0 else None,
        payload_mass_kg=payload_kg if payload_kg > 0 else None,
        reference_body=scenario.reference_body,
    )
    try:
        return _fly(env.unwrapped, env, req, scenario, platform, payload_kg, seconds)
    finally:
        env.close()


def _fly(base, env, req, scenario, platform, payload_kg, seconds) -> FlightResult:
    env.reset(seed=req.seed)
    agent, bc = base.agent, base.agent.body_controller
    bc.telemetry = []
    holding = payload_kg > 0 or scenario.reference_body  # fingers closed on the object (or on each other)
    action = torch.zeros(1, platform.action_dim)
    action[:, -1] = -1.0 if holding else 1.0
    if platform.arm is not None:
        action[:, 4:7] = bc.arm_action(torch.tensor(platform.arm.working_pose_rad))
    memo: dict = {}
    grasped, control_t, frames = [], [], []
    for k in range(int(round(seconds * CONTROL_HZ))):
        t = k / CONTROL_HZ
        position = agent.airframe_state().position[0].cpu().numpy()
        velocity, yaw_rate = scenario.command(scenario, t, position, memo)
        action[:, :3] = torch.as_tensor(np.clip(velocity / MAX_SPEED_MPS, -1, 1), dtype=torch.float32)
        action[:, 3] = float(np.clip(yaw_rate / MAX_YAW_RATE_RPS, -1, 1))
        _, _, _, _, info = env.step(action)
        control_t.append(t)
        if "is_grasped" in info:
            grasped.append(bool(info["is_grasped"][0]))
        if req.video and k % VIDEO_EVERY_N_CONTROL_STEPS == 0:
            frames.append(env.render()[0].cpu().numpy())
        if scenario.done is not None and scenario.done(memo, t):
            break
    trace = _trace(bc.telemetry, control_t, grasped, base, payload_kg, memo)
    metrics = {
        "platform": req.platform,
        "scenario": req.scenario,
        "controller": req.controller,
        "seconds": float(trace.t[-1] + 1.0 / PHYSICS_HZ),
        "payload_kg": payload_kg,
        **scenario.metrics(trace, platform),
    }
    if req.plot:
        from .plots import plot_flight

        plot_flight(trace, platform, Path(req.plot), title=f"{req.platform} / {req.scenario} / {req.controller}")
    if req.video:
        write_video(frames, Path(req.video), fps=CONTROL_HZ // VIDEO_EVERY_N_CONTROL_STEPS)
    return FlightResult(metrics, trace, frames)


def _trace(telemetry, control_t, grasped, base, payload_kg, memo) -> Trace:
    def stack(key):
        return torch.stack([step[key][0] for step in telemetry]).cpu().numpy()

    ref = getattr(base, "reference_telemetry", None)
    return Trace(
        t=np.arange(len(telemetry)) / PHYSICS_HZ,
        position=stack("position"),
        velocity=stack("velocity"),
        yaw_rate=stack("yaw_rate"),
        tilt_cos=stack("tilt_cos"),
        xi=stack("xi"),
        rotor_thrusts=stack("rotor_thrusts"),
        mass_hat=stack("mass_hat"),
        control_t=np.asarray(control_t),
        is_grasped=np.asarray(grasped) if grasped else None,
        reference_position=torch.stack(ref).numpy() if ref else None,
        payload_kg=payload_kg,
        extra={"memo": memo},
    )


__all__ = ["FlightRequest", "FlightResult", "fly"]
