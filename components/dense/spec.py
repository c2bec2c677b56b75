"""The dense layer: the bundle-level spec."""
from __future__ import annotations

from inshade.components.spec import MAX_WIDTH, ComponentSpec, Param, TensorSpec, pos_int, register


PRECISIONS = ("f32", "f16", "i8")   # inshade/quantize.py: what each stores and how it decodes


def _tensors(p, d) -> dict:
    """f16: weights and biases float16 values; i8: each weight row int8 codes times its weight_scale."""
    half = "float16" if p["precision"] == "f16" else None
    scaled = p["precision"] == "i8"
    return {"weight": TensorSpec((p["out"], d), "float32", half, scaled_by="weight_scale" if scaled else None),
            **({"bias": TensorSpec((p["out"],), "float32", half)} if p["bias"] else {}),
            **({"weight_scale": TensorSpec((p["out"],), "float32")} if scaled else {})}


register(ComponentSpec(
    "dense", "y = W x + b, W stored [out, in] like torch.nn.Linear",
    {"out": Param(int, check=pos_int(MAX_WIDTH)), "bias": Param(bool, True),
     "precision": Param(str, "f32", lambda v: v in PRECISIONS,
                        doc="weight storage: f32, f16 (biases too) or i8 (per output row, scale weight_scale)")},
    out_dim=lambda p, d: p["out"],
    tensors=_tensors,
    in_dim=lambda p, d: 1 <= d <= MAX_WIDTH,
    category="layer",
))

# codegen options of a dense layer (its emitter declares them): where the weights live, and the
# texel format of the weight texture (float32 or float16). `ssbo` (a read-only storage buffer per
# layer) is for the languages that have them (Vulkan, WebGPU, D3D); OpenGL's GLSL 3.30 and ES 3.00 do not.
STORAGE_MODES = ("inline", "ubo", "texture", "ssbo", "auto")
OPENGL_STORAGE_MODES = ("inline", "ubo", "texture", "auto")
TEXTURE_FORMATS = ("f4", "f2")
# how a layer's products are computed: float32; float16 (GL_EXT_shader_explicit_arithmetic_types_float16
# on Vulkan, `enable f16` in WGSL) with the sums in float16 too, or with the sums in float32 (each mat4
# block's product in float16). The weights must be float16 values (precision f16) so that none is rounded.
ARITHMETIC = ("f32", "f16", "f16_acc32")
# the texels an i8 layer's codes (+ 128) sit in with storage texture: RGBA8UI, read as integers (llvmpipe
# compiles those fetches in a fraction of an unorm8 fetch's time), or RGBA8 unorm (an image file's
# texels: what an engine imports)
I8_TEXELS = {"uint": "u1", "unorm": "f1"}
