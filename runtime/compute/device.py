"""The wgpu device the compute targets run on, opened once per process."""
from __future__ import annotations

import importlib
import logging
import os
import tempfile
from dataclasses import dataclass
from functools import lru_cache

from .textures import FEATURES as TEXTURE_FEATURES

WGPU_BACKENDS = ["Vulkan", "Metal", "DX12"]
INSTALL_HINT = "pip install 'inshade[compute]' (wgpu) and a Vulkan driver (Debian: mesa-vulkan-drivers)"

# the device's limits under the GL names codegen plans with (codegen/targets.py)
PLANNING_LIMITS = {
    "GL_MAX_TEXTURE_SIZE": "max_texture_dimension_2d",
    "GL_MAX_3D_TEXTURE_SIZE": "max_texture_dimension_3d",
    "GL_MAX_ARRAY_TEXTURE_LAYERS": "max_texture_array_layers",
    "GL_MAX_UNIFORM_BLOCK_SIZE": "max_uniform_buffer_binding_size",
    "GL_MAX_FRAGMENT_UNIFORM_BLOCKS": "max_uniform_buffers_per_shader_stage",
    "GL_MAX_TEXTURE_IMAGE_UNITS": "max_sampled_textures_per_shader_stage",
    "GL_MAX_COMBINED_TEXTURE_IMAGE_UNITS": "max_sampled_textures_per_shader_stage",
    "GL_MAX_SHADER_STORAGE_BLOCK_SIZE": "max_storage_buffer_binding_size",
    "GL_MAX_FRAGMENT_SHADER_STORAGE_BLOCKS": "max_storage_buffers_per_shader_stage",
    "GL_MAX_DRAW_BUFFERS": "max_color_attachments",
}


class _DroppedDecorations(logging.Filter):
    """wgpu's SPIR-V reader (naga) warns once per use that it drops ``precise`` (the NoContraction
    decoration): a note about its own reading, not about the code, whose results are checked anyway."""

    def filter(self, record: logging.LogRecord) -> bool:
        return "Unknown decoration NoContraction" not in record.getMessage()


class ShaderBuildError(RuntimeError):
    """A generated source its language's compiler refused (the compiler's log attached)."""


class ComputeUnavailable(RuntimeError):
    """No wgpu, or no device it can open."""


@dataclass
class ComputeDevice:
    wgpu: object
    device: object
    name: str           # e.g. "llvmpipe (LLVM 15.0.6, 256 bits)"
    backend: str        # e.g. "Vulkan"
    limits: dict        # the device's limits, wgpu's names (snake_case)

    @property
    def description(self) -> str:
        return f"{self.name} ({self.backend})"

    def planning_limits(self) -> dict:
        """This device's limits as codegen plans with them, with its name (software renderers plan
        their own way, codegen/mlp.py)."""
        out = {gl: int(self.limits[key]) for gl, key in PLANNING_LIMITS.items() if key in self.limits}
        return {**out, "renderer": self.name}


@lru_cache(maxsize=1)
def compute_device() -> ComputeDevice:
    """The process's device: the adapter wgpu prefers, opened with every limit it offers."""
    if not os.environ.get("XDG_RUNTIME_DIR"):
        # Mesa's Vulkan drivers print "XDG_RUNTIME_DIR is invalid" on every device a process opens without one
        os.environ["XDG_RUNTIME_DIR"] = tempfile.mkdtemp(prefix="inshade-runtime-")
    try:
        wgpu = importlib.import_module("wgpu")
    except ImportError as e:
        raise ComputeUnavailable(f"the WebGPU/Vulkan/HLSL targets run through wgpu: {INSTALL_HINT}") from e
    # every backend but OpenGL: wgpu's GL backend makes its own EGL context current, which takes the
    # GL runtime's context away from it in the same process
    logging.getLogger("wgpu").addFilter(_DroppedDecorations())
    extras = importlib.import_module("wgpu.backends.wgpu_native.extras")
    extras.set_instance_extras(backends=WGPU_BACKENDS)
    adapter = wgpu.gpu.request_adapter_sync(power_preference="high-performance")
    if adapter is None:
        raise ComputeUnavailable(f"wgpu found no device: {INSTALL_HINT}")
    limits = {k.replace("-", "_"): v for k, v in adapter.limits.items()}
    features = [f for f in (*TEXTURE_FEATURES, "shader-f16") if f in adapter.features]   # f16: float16 arithmetic
    device = adapter.request_device_sync(required_limits=dict(adapter.limits), required_features=features)
    info = adapter.info
    return ComputeDevice(wgpu, device, str(info.get("device", "?")), str(info.get("backend_type", "?")), limits)
