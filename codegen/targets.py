"""The shading languages codegen writes, each with its printer and the limits it plans against
when the caller hands none.

A target's limits are stored under the GL names the planner reads (uniform block bytes, texture
sides, blocks and samplers per stage), each with where it comes from in that API's own words, so
a plan or a refusal names the target's limit. A caller's dict (a queried device's) overrides them.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from .printers.base import Printer
from .printers.glsl import GLSLPrinter, VulkanGLSLPrinter
from .printers.hlsl import HLSLPrinter, SlangPrinter
from .printers.wgsl import WGSLPrinter


class TargetError(ValueError):
    """A network that a target cannot express (a component without a lowering for it)."""


@dataclass(frozen=True)
class Target:
    name: str
    printer: Printer
    about: str
    extension: str                   # of a written file
    opengl: bool = False             # a chunk inshade's GL runtime assembles (#include lines kept)
    limits: dict = field(default_factory=dict)    # GL name -> (value, the API's name for it)


def _limits(api: str, **by_gl_name) -> dict:
    return {f"GL_{k}": (value, f"{api} {name}") for k, (value, name) in by_gl_name.items()}


# WebGPU's default limits (what a page gets without asking for more)
WEBGPU = _limits(
    "WebGPU default", MAX_TEXTURE_SIZE=(8192, "maxTextureDimension2D"),
    MAX_3D_TEXTURE_SIZE=(2048, "maxTextureDimension3D"), MAX_ARRAY_TEXTURE_LAYERS=(256, "maxTextureArrayLayers"),
    MAX_UNIFORM_BLOCK_SIZE=(65536, "maxUniformBufferBindingSize"),
    MAX_FRAGMENT_UNIFORM_BLOCKS=(12, "maxUniformBuffersPerShaderStage"),
    MAX_TEXTURE_IMAGE_UNITS=(16, "maxSampledTexturesPerShaderStage"),
    MAX_COMBINED_TEXTURE_IMAGE_UNITS=(16, "maxSampledTexturesPerShaderStage"),
    MAX_SHADER_STORAGE_BLOCK_SIZE=(134217728, "maxStorageBufferBindingSize"),
    MAX_FRAGMENT_SHADER_STORAGE_BLOCKS=(8, "maxStorageBuffersPerShaderStage"),
    MAX_DRAW_BUFFERS=(8, "maxColorAttachments"))
# Direct3D 11 at feature level 11_0 (the floor Unity and Unreal ship for D3D11 and D3D12)
D3D11 = _limits(
    "D3D11 feature level 11_0", MAX_TEXTURE_SIZE=(16384, "D3D11_REQ_TEXTURE2D_U_OR_V_DIMENSION"),
    MAX_3D_TEXTURE_SIZE=(2048, "D3D11_REQ_TEXTURE3D_U_V_OR_W_DIMENSION"),
    MAX_ARRAY_TEXTURE_LAYERS=(2048, "D3D11_REQ_TEXTURE2D_ARRAY_AXIS_DIMENSION"),
    MAX_UNIFORM_BLOCK_SIZE=(65536, "D3D11_REQ_CONSTANT_BUFFER_ELEMENT_COUNT x 16 B"),
    MAX_FRAGMENT_UNIFORM_BLOCKS=(14, "D3D11_COMMONSHADER_CONSTANT_BUFFER_API_SLOT_COUNT"),
    MAX_TEXTURE_IMAGE_UNITS=(128, "D3D11_COMMONSHADER_INPUT_RESOURCE_SLOT_COUNT"),
    MAX_COMBINED_TEXTURE_IMAGE_UNITS=(128, "D3D11_COMMONSHADER_INPUT_RESOURCE_SLOT_COUNT"),
    MAX_SHADER_STORAGE_BLOCK_SIZE=(134217728, "D3D11_REQ_RESOURCE_SIZE_IN_MEGABYTES_EXPRESSION_A_TERM (128 MiB)"),
    MAX_FRAGMENT_SHADER_STORAGE_BLOCKS=(128, "D3D11_COMMONSHADER_INPUT_RESOURCE_SLOT_COUNT"),
    MAX_DRAW_BUFFERS=(8, "D3D11_SIMULTANEOUS_RENDER_TARGET_COUNT"))
# Vulkan 1.0's required minimums (every conformant driver has at least these)
VULKAN = _limits(
    "Vulkan minimum", MAX_TEXTURE_SIZE=(4096, "maxImageDimension2D"),
    MAX_3D_TEXTURE_SIZE=(256, "maxImageDimension3D"), MAX_ARRAY_TEXTURE_LAYERS=(256, "maxImageArrayLayers"),
    MAX_UNIFORM_BLOCK_SIZE=(16384, "maxUniformBufferRange"),
    MAX_FRAGMENT_UNIFORM_BLOCKS=(12, "maxPerStageDescriptorUniformBuffers"),
    MAX_TEXTURE_IMAGE_UNITS=(16, "maxPerStageDescriptorSampledImages"),
    MAX_COMBINED_TEXTURE_IMAGE_UNITS=(16, "maxPerStageDescriptorSampledImages"),
    MAX_SHADER_STORAGE_BLOCK_SIZE=(134217728, "maxStorageBufferRange"),
    MAX_FRAGMENT_SHADER_STORAGE_BLOCKS=(4, "maxPerStageDescriptorStorageBuffers"),
    MAX_DRAW_BUFFERS=(4, "maxColorAttachments"))

_GL = GLSLPrinter()
TARGETS = {t.name: t for t in (
    Target("330", _GL, "GLSL 3.30 core (OpenGL 3.3+)", "glsl", opengl=True),
    Target("450", _GL, "GLSL 4.50 core (OpenGL 4.5)", "glsl", opengl=True),
    Target("es300", _GL, "GLSL ES 3.00 (WebGL2, OpenGL ES 3)", "glsl", opengl=True),
    Target("vulkan", VulkanGLSLPrinter(), "GLSL 4.50 for Vulkan (set/binding layout; glslang -V)", "glsl",
           limits=VULKAN),
    Target("wgsl", WGSLPrinter(), "WGSL (WebGPU)", "wgsl", limits=WEBGPU),
    Target("hlsl", HLSLPrinter(), "HLSL, Shader Model 5.0 and 6.x (D3D11/12, Unity, Unreal)", "hlsl", limits=D3D11),
    Target("slang", SlangPrinter(), "Slang (a module to import; planned against Vulkan's minimums)", "slang",
           limits=VULKAN),
)}


# the OpenGL targets: chunks inshade's GL runtime assembles and runs
GL_TARGETS = tuple(name for name, t in TARGETS.items() if t.opengl)


def target(name: str) -> Target:
    if name not in TARGETS:
        raise ValueError(f"unknown target {name!r} (choose from {', '.join(TARGETS)})")
    return TARGETS[name]


def planning_limits(t: Target, given: dict | None) -> dict:
    """The limits to plan against: the caller's, over the target's own (with where each comes from)."""
    limits = {name: value for name, (value, _) in t.limits.items()}
    sources = {name: about for name, (_, about) in t.limits.items()}
    given = dict(given or {})
    for name in given:
        sources.pop(name, None)
    return {**limits, **given, **({"limit_sources": sources} if sources else {})}
