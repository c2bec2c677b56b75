"""Small glTF files that a trainer must refuse with one error line, made at test time."""
from __future__ import annotations

from pathlib import Path

import numpy as np


def textured_without_uv(path) -> Path:
    """One triangle whose material reads a base-colour texture, with no TEXCOORD_0 to read it at."""
    from inshade.geometry.gltf_write import GltfBuilder, Primitive

    b = GltfBuilder()
    material = b.material({"pbrMetallicRoughness": {"baseColorTexture": {"index": b.texture(b.image(
        np.full((4, 4, 4), 200, np.uint8)))}}})
    b.node(b.mesh([Primitive(np.eye(3), np.array([[0, 1, 2]]), material=material)]))
    return b.write(path)
