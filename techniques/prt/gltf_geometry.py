"""A glTF file as PRT geometry: the mesh the runtime draws for it (geometry/gltf.py: every triangle
of the default scene in world space, vertices not merged) carrying the file's own normals as its
vertex normals, so that the transfer is learnt at the normals the G-buffer interpolates (trimesh
would otherwise average face normals over each primitive's shared vertices).

numpy + trimesh; no torch.
"""
from __future__ import annotations

import numpy as np
import trimesh

from inshade.geometry.gltf import load_gltf


def gltf_mesh(path) -> trimesh.Trimesh:
    """The world-space mesh of the glTF file ``path`` with its normals (GltfError ``FILE: FIELD:
    problem`` when the file cannot be read)."""
    drawn = load_gltf(path).mesh
    normals = np.asarray(drawn.vertex_attributes["normal"], np.float64)
    mesh = trimesh.Trimesh(np.asarray(drawn.vertices), np.asarray(drawn.faces), vertex_normals=normals,
                           process=False, validate=False)
    # the normals are part of what the transfer depends on (transfer_dataset.geometry_digest)
    mesh.vertex_attributes["normal"] = normals
    return mesh
