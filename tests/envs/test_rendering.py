"""Ray-traced rendering (spec appendix "Ray Tracing"): the device check, the one-line refusal where a machine cannot,
and, on a ray-tracing GPU, cameras that actually render through it."""

import os
import subprocess
import sys

import gymnasium as gym
import pytest

import aerobench.envs  # noqa: F401
from aerobench.envs.rendering import (
    check_rendering,
    parse_device_summary,
    ray_traced_shader,
    ray_tracing_device,
    require_ray_tracing,
)
from aerobench.rollout.runner import RolloutSpec

LAVAPIPE = """GPU: llvmpipe (LLVM 15.0.6, 256 bits)
  Supported: 1
  Present:   0
  cudaId:    -1
  rayTrace:  1
  cudaMode   -1
"""
H100_AND_RTX = """GPU: NVIDIA H100 80GB HBM3
  Supported: 1
  Present:   0
  cudaId:    0
  rayTrace:  0
  cudaMode   1
GPU: NVIDIA GeForce RTX 4090
  Supported: 1
  Present:   1
  cudaId:    1
  rayTrace:  1
  cudaMode   1
"""


def test_device_summary_is_parsed_per_device():
    devices = parse_device_summary(H100_AND_RTX)
    assert [(d.name, d.ray_tracing, d.cuda_id) for d in devices] == [
        ("NVIDIA H100 80GB HBM3", False, 0), ("NVIDIA GeForce RTX 4090", True, 1)]
    assert ray_tracing_device(H100_AND_RTX).name == "NVIDIA GeForce RTX 4090"
    assert ray_tracing_device(H100_AND_RTX.split("GPU: NVIDIA GeForce")[0]) is None  # an H100 alone cannot


def test_software_vulkan_counts_as_unable_with_a_one_line_reason():
    assert ray_tracing_device(LAVAPIPE) is None  # it claims ray tracing, and renders black
    with pytest.raises(ValueError) as e:
        require_ray_tracing(LAVAPIPE)
    message = str(e.value)
    assert "\n" not in message and "llvmpipe" in message and "rasterized" in message


def test_without_cuda_the_optix_denoiser_is_left_out():
    amd = "GPU: AMD Radeon RX 7900\n  cudaId: -1\n  rayTrace: 1\n"
    assert ray_traced_shader(require_ray_tracing(amd)).shader_pack_config["ray_tracing_denoiser"] == "none"
    assert ray_traced_shader(require_ray_tracing(H100_AND_RTX)).shader_pack_config["ray_tracing_denoiser"] == "optix"


def test_rendering_names_are_checked_and_recorded_only_when_not_the_default():
    with pytest.raises(ValueError, match="rasterized, ray-traced"):
        check_rendering("path-traced")
    spec = RolloutSpec(setting="TidyHouse", skills=("pick",), episodes=1)
    assert "rendering" not in spec.as_dict()  # runs made before the option stay resumable
    assert RolloutSpec(setting="TidyHouse", skills=("pick",), episodes=1, rendering="ray-traced").as_dict()["rendering"] == "ray-traced"
    with pytest.raises(ValueError, match="drop --no-cameras"):
        RolloutSpec(setting="TidyHouse", skills=("pick",), episodes=1, rendering="ray-traced", record_cameras=False)


@pytest.mark.skipif(ray_tracing_device() is not None, reason="this machine has a ray-tracing GPU (the GPU test runs)")
def test_env_and_generator_refuse_in_one_line_where_the_machine_cannot(tmp_path):
    with pytest.raises(ValueError, match="needs a GPU with Vulkan ray tracing"):
        gym.make("AeroPick-v1", setting="TidyHouse", obs_mode="rgbd", rendering="ray-traced")
    env = dict(os.environ, HF_HUB_OFFLINE="1", MS_SKIP_ASSET_DOWNLOAD_PROMPT="1")
    r = subprocess.run([sys.executable, "-m", "aerobench.cli", "generate", "--setting", "TidyHouse", "--skills", "pick",
                        "--episodes", "1", "--render", "ray-traced", "--out", str(tmp_path / "ds")],
                       capture_output=True, text=True, timeout=300, env=env)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert r.stderr.strip().startswith("aerobench generate: error: ray-traced rendering needs a GPU")
    assert len(r.stderr.strip().splitlines()) == 1 and not (tmp_path / "ds").exists()


@pytest.mark.gpu
@pytest.mark.skipif(ray_tracing_device() is None, reason="needs a GPU with Vulkan ray tracing (none on this machine)")
def test_ray_traced_cameras_render_a_lit_scene():
    env = gym.make("AeroPick-v1", setting="TidyHouse", obs_mode="rgbd", rendering="ray-traced")
    try:
        obs, _ = env.reset(seed=0)
        for camera in obs["sensor_data"].values():
            assert camera["rgb"].float().mean() > 10  # software Vulkan gives ~0.02
    finally:
        env.close()
