"""The dense layer: the bundle-level spec."""
from __future__ import annotations

from inshade.components.spec import MAX_WIDTH, ComponentSpec, Param, TensorSpec, pos_int, register


register(ComponentSpec(
    "dense", "y = W x + b, W stored [out, in] like torch.nn.Linear",
    {"out": Param(int, check=pos_int(MAX_WIDTH)), "bias": Param(bool, True)},
    out_dim=lambda p, d: p["out"],
    tensors=lambda p, d: {"weight": TensorSpec((p["out"], d), "float32"),
                          **({"bias": TensorSpec((p["out"],), "float32")} if p["bias"] else {})},
    in_dim=lambda p, d: 1 <= d <= MAX_WIDTH,
    category="layer",
))

# codegen options of a dense layer (its emitter declares them): where the weights live, and the
# texel format of the weight texture (float32 or float16). `ssbo` (a read-only storage buffer per
# layer) is for the languages that have them (Vulkan, WebGPU, D3D); OpenGL's GLSL 3.30 and ES 3.00 do not.
STORAGE_MODES = ("inline", "ubo", "texture", "ssbo", "auto")
OPENGL_STORAGE_MODES = ("inline", "ubo", "texture", "auto")
TEXTURE_FORMATS = ("f4", "f2")
