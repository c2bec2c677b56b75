"""Which material of a glTF asset's mesh is neural, and where its latents lie in uv: the asset's
``gltf_material.json``, written by the trainer (gltf_source.py) and read by the glTF pass's hooks
(``<na_gltf_info>``). json only: the technique record imports this.

    {"format": "inshade.neural_appearance.gltf", "version": 1, "source": "source.glb",
     "material": 1, "material_name": "brushed metal", "uv_min": [0, 0], "uv_max": [1, 1]}

The latent pyramid covers the material's uv bounding box: latent coordinates are
``(uv - uv_min) / (uv_max - uv_min)`` (uv in the project's convention, v up), so a mesh whose uv
run past [0, 1] (a torus tiled twice) keeps every texel of its material distinct.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

INFO_FILE = "gltf_material.json"
FORMAT = "inshade.neural_appearance.gltf"


def info_path(scene) -> Path:
    if scene.root is None:
        raise ValueError(f"scene '{scene.name}': a neural glTF material lives in an asset folder holding {INFO_FILE}")
    return Path(scene.root) / INFO_FILE


def read_info(path) -> dict:
    """The checked contents of a ``gltf_material.json`` (ValueError naming the file and field)."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: missing (which glTF material is neural, and its uv box)")
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not valid JSON: {exc}") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ValueError(f"{path}: format: expected {FORMAT!r}")
    m = data.get("material")
    if isinstance(m, bool) or not isinstance(m, int) or m < 0:
        raise ValueError(f"{path}: material: expected a material index, got {m!r}")
    for key in ("uv_min", "uv_max"):
        box = data.get(key)
        if not (isinstance(box, list) and len(box) == 2 and all(isinstance(x, (int, float)) and math.isfinite(x)
                                                                for x in box)):
            raise ValueError(f"{path}: {key}: expected [u, v], got {box!r}")
    if not all(hi > lo for lo, hi in zip(data["uv_min"], data["uv_max"])):
        raise ValueError(f"{path}: uv_max: must exceed uv_min in u and v, got {data['uv_min']} .. {data['uv_max']}")
    return data


def write_info(path, *, source: str, material: int, material_name: str, uv_min, uv_max) -> dict:
    from inshade.files import atomic_write

    data = {"format": FORMAT, "version": 1, "source": source, "material": int(material),
            "material_name": material_name, "uv_min": [float(x) for x in uv_min],
            "uv_max": [float(x) for x in uv_max]}
    atomic_write(Path(path), json.dumps(data, indent=1) + "\n")
    return data


def info_chunk(data: dict) -> str:
    """``<na_gltf_info>``: the neural material's index and the uv -> latent map of lib/na_gltf."""
    scale = [1.0 / (hi - lo) for lo, hi in zip(data["uv_min"], data["uv_max"])]
    vec = lambda x: f"vec2({x[0]:.9g}, {x[1]:.9g})"   # noqa: E731
    return (f"#define NA_GLTF_MATERIAL {int(data['material'])}\n"
            f"#define NA_UV_ORIGIN {vec(data['uv_min'])}\n"
            f"#define NA_UV_SCALE {vec(scale)}\n")
