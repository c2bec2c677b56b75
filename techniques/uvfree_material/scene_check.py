"""The scene's mesh must be the one the material bundle was trained on: its features are
addressed by face id, so the same faces in the same order with the same welded topology
(geometry/mesh_topology.py digest, recorded in the bundle's provenance by train.py)."""
from __future__ import annotations

import json
from pathlib import Path

from inshade.geometry.mesh_topology import MeshTopologyError, weld, topology_digest


def _bundle_meta(ref) -> dict:
    path = Path(ref.bundle)
    path = path / "bundle.json" if path.is_dir() else path
    return json.loads(path.read_text())


def check_mesh_matches(scene, ref) -> None:
    meta = _bundle_meta(ref)
    nodes = [n for n in meta.get("nodes", []) if n.get("type") == "mesh_features"]
    if len(nodes) != 1:
        raise ValueError(f"networks: {ref.bundle}: a uvfree_material bundle has one mesh_features node, has {len(nodes)}")
    faces = scene.mesh.data.faces
    want = int(nodes[0]["params"]["faces"])
    name = scene.mesh.name
    if len(faces) != want:
        raise ValueError(f"mesh: {name} has {len(faces)} faces; the material bundle was trained on {want} "
                         f"(features are addressed by face id)")
    digest = meta.get("provenance", {}).get("mesh_digest")
    if digest is None:
        return   # a bundle made by hand: the face count is all there is to check
    try:
        welded, _ = weld(scene.mesh.data.vertices, faces)
    except MeshTopologyError as exc:
        raise ValueError(f"mesh: {name}: {exc}") from None
    if topology_digest(welded) != digest:
        raise ValueError(f"mesh: {name} is not the mesh the material bundle was trained on (welded topology "
                         f"{topology_digest(welded)}, the bundle's {digest}): same face count, other faces or order")
