"""The UV-free material network: (triangle id, barycentrics) -> mesh_features -> MLP -> 9 channels.

Channels (``CHANNELS``, the bundle's output ``material``) are the texel values the reference
textures store, so decoded and reference go through the same unpacking in the shader:
albedo sRGB-encoded RGB, the tangent-space normal as n * 0.5 + 0.5, roughness, metallic, AO.

Configurations follow the thesis's memory/balanced/quality triple (Table 6.2): features of
length F = 4, levels L from the texel density (the finest level's sub-triangles about one texel
wide, the thesis's "low vertex density needs more levels"), and the hash-table size T the largest
power of two whose fp16 features fit the configuration's share of the uncompressed textures
(1/12, 1/6, 1/3: the thesis's 8.3 %, 16.7 %, 33.3 % rates).
"""
from __future__ import annotations

import math

from inshade.components.elementwise.torch_twin import ReLU
from inshade.components.mesh_features.torch_twin import MeshFeatures
from inshade.models import GraphModule

KIND = "uvfree_material"
CHANNELS = ("albedo_r", "albedo_g", "albedo_b", "normal_x", "normal_y", "normal_z", "roughness", "metallic", "ao")
GROUPS = {"albedo": (0, 3), "normal": (3, 6), "rma": (6, 9)}
FEATURES = 4
CONFIGS = {"memory": 1 / 12, "balanced": 1 / 6, "quality": 1 / 3}   # share of the uncompressed bytes
HIDDEN = (64, 64, 64, 64)   # the thesis decoder: 4 hidden layers of 64, ReLU
MAX_LEVELS = 8


def choose_levels(faces: int, area_fraction_texels: float) -> int:
    """Levels so the finest sub-triangles are about a texel: a face covers ``texels / faces``
    texels, i.e. about sqrt(2 texels / faces) along an edge."""
    edge = math.sqrt(2.0 * max(area_fraction_texels, 1.0) / max(faces, 1))
    return max(2, min(MAX_LEVELS, int(round(math.log2(max(edge, 1.0)))) + 1))


def choose_table_size(budget_bytes: float, levels: int, features: int = FEATURES) -> int:
    """The largest power of two T with 2 bytes * levels * T * features <= budget (at least 2^4)."""
    t = int(budget_bytes // (2 * levels * features))
    return 1 << max(4, t.bit_length() - 1)


def material_graph(vertices, faces, *, levels: int, table_size: int, features: int = FEATURES,
                   hidden=HIDDEN, precision: str = "f16", seed: int = 0, outputs: int = len(CHANNELS)) -> GraphModule:
    """The network on a mesh; ``outputs`` channels (``CHANNELS``; a glTF file's: gltf_channels.py)."""
    g = GraphModule([("triangle", 1, "triangle_id", "uint"), ("barycentric", 2, "barycentric")])
    enc = MeshFeatures.for_mesh(vertices, faces, levels, features, table_size, precision=precision, seed=seed)
    src = g.add("features", enc, ["triangle", "barycentric"])
    for i, width in enumerate(hidden):
        src = g.dense(f"l{i}", src, width)
        src = g.add(f"a{i}", ReLU(), src)
    src = g.dense(f"l{len(hidden)}", src, outputs)
    g.output("material", src, "material_channels")
    return g
