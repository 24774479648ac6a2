"""How the cameras render: SAPIEN's rasterizer (default) or its ray tracer (spec appendix "Ray Tracing").

Ray tracing needs a Vulkan device with hardware ray tracing. SAPIEN lists Mesa's software device (llvmpipe /
lavapipe) as ray-tracing capable, but there the ray-traced images come out black (AeroPick-v1 wrist camera, mean RGB
0.02 of 255 against 134 rasterized, measured 2026-11-25), so software devices count as unable. The denoiser SAPIEN
uses by default is NVIDIA OptiX; on a ray-tracing device without CUDA the images are rendered without one.
"""

from __future__ import annotations

import dataclasses
import re

RENDERINGS = ("rasterized", "ray-traced")
DEFAULT_RENDERING = "rasterized"
SOFTWARE_VULKAN = ("llvmpipe", "lavapipe", "swiftshader")


def check_rendering(rendering: str) -> str:
    name = str(rendering).strip().lower()
    if name not in RENDERINGS:
        raise ValueError(f"rendering {rendering!r}; use one of {', '.join(RENDERINGS)}")
    return name


@dataclasses.dataclass(frozen=True)
class VulkanDevice:
    name: str
    ray_tracing: bool
    cuda_id: int

    @property
    def is_software(self) -> bool:
        return any(s in self.name.lower() for s in SOFTWARE_VULKAN)


def parse_device_summary(summary: str) -> list[VulkanDevice]:
    """The devices of `sapien.render.get_device_summary()` (one `GPU: name` block of `key: value` lines each)."""
    devices, block = [], None
    for line in summary.splitlines():
        head = re.match(r"\s*GPU:\s*(.+)$", line)
        if head:
            block = {"name": head.group(1).strip()}
            devices.append(block)
            continue
        field = re.match(r"\s*(rayTrace|cudaId)\s*:?\s*(-?\d+)", line)
        if field and block is not None:
            block[field.group(1)] = int(field.group(2))
    return [VulkanDevice(d["name"], d.get("rayTrace", 0) == 1, d.get("cudaId", -1)) for d in devices]


def device_summary() -> str:
    import sapien

    return sapien.render.get_device_summary()


def ray_tracing_device(summary: str | None = None) -> VulkanDevice | None:
    """The first hardware Vulkan device that ray-traces, or None."""
    summary = device_summary() if summary is None else summary
    usable = [d for d in parse_device_summary(summary) if d.ray_tracing and not d.is_software]
    return usable[0] if usable else None


def require_ray_tracing(summary: str | None = None) -> VulkanDevice:
    """The ray-tracing device, or a one-line error that says what this machine has and what to do."""
    summary = device_summary() if summary is None else summary
    device = ray_tracing_device(summary)
    if device is None:
        found = ", ".join(d.name for d in parse_device_summary(summary)) or "no Vulkan device"
        raise ValueError(f"ray-traced rendering needs a GPU with Vulkan ray tracing (an NVIDIA RTX-class card); this "
                         f"machine has {found}, which cannot (software Vulkan renders black); use rasterized rendering")
    return device


def ray_traced_shader(device: VulkanDevice):
    """ManiSkill's full-quality ray-tracing shader config, with OptiX denoising only where CUDA is there."""
    from mani_skill.render.shaders import PREBUILT_SHADER_CONFIGS

    config = PREBUILT_SHADER_CONFIGS["rt"]
    if device.cuda_id < 0:
        config = dataclasses.replace(config, shader_pack_config={**config.shader_pack_config,
                                                                 "ray_tracing_denoiser": "none"})
    return config


def ray_traced_camera_overrides(sensor_configs: dict | None, human_render_camera_configs: dict | None
                                ) -> tuple[dict, dict]:
    """ManiSkill camera-config overrides that make every camera (sensors and the third-person view) ray-traced.

    Raises the one-line error of `require_ray_tracing` on a machine that cannot; the caller's own keys win.
    """
    shader = ray_traced_shader(require_ray_tracing())
    return ({"shader_config": shader, **(sensor_configs or {})},
            {"shader_config": shader, **(human_render_camera_configs or {})})
