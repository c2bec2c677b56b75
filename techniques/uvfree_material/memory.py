"""What a UV-free material costs in GPU memory, against the uncompressed textures it replaces
(torch-free: the trainer's metrics and the bench share it).

Bytes as the generated code's resources hold them (components/mesh_features/emit.py): the feature-table
textures (fp16, or unorm8 for precision u8, whose per-lane scale/offset float32 constants count
with them), the owner-table texture (12, 16 or 24 bytes per face as the mesh's size allows:
components/mesh_features/emit.py TOPOLOGY_LAYOUTS) and the MLP's fp32 weights (literals or a uniform block).
The thesis counts features and MLP only; the owner tables are reported beside them, since a
renderer holds them too.
"""
from __future__ import annotations

TEXTURES = 3   # albedo, normal, roughness/metallic/AO: three RGB8 maps


def reference_bytes(width: int, height: int | None = None) -> int:
    """The uncompressed textures: three RGB8 maps of width x height texels."""
    return TEXTURES * 3 * width * (width if height is None else height)


def network_bytes(bundle) -> tuple[int, int, int]:
    """(features, MLP, owner tables) bytes of a material bundle's GPU resources."""
    from inshade.codegen import generate

    textures = [r for r in generate(bundle).resources if hasattr(r, "dtype")]
    feats = sum(r.nbytes for r in textures if "_table" in r.name)
    feats += sum(bundle.tensors[n.tensor_name(slot)].size * 4 for n in bundle.nodes
                 if n.type == "mesh_features" for slot in ("scale", "offset") if n.tensor_name(slot) in bundle.tensors)
    topo = sum(r.nbytes for r in textures if r.name.endswith("_topology"))
    mlp = sum(a.size * 4 for name, a in bundle.tensors.items() if name.endswith((".weight", ".bias")))
    return int(feats), int(mlp), int(topo)


def memory_report(bundle, width: int, height: int | None = None) -> dict:
    feats, mlp, topo = network_bytes(bundle)
    ref = reference_bytes(width, height)
    precision = next((n.params["precision"] for n in bundle.nodes if n.type == "mesh_features"), "f16")
    return {"features_precision": precision, "features_bytes": int(feats), "mlp_bytes": int(mlp),
            "topology_bytes": int(topo),
            "neural_bytes": int(feats + mlp), "neural_bytes_all": int(feats + mlp + topo), "reference_bytes": ref,
            "texture_size": [int(width), int(height or width)], "rate_features_mlp": round((feats + mlp) / ref, 4),
            "rate_all": round((feats + mlp + topo) / ref, 4)}
