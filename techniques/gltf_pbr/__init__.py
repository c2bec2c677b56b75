"""gltf_pbr: a glTF 2.0 asset drawn with the spec's reference shading (appendix B's BRDF and the KHR
lobes, shaders/lib/gltf_brdf.glsl + lib/gltf_material.glsl; numpy twin models/gltf_brdf.py), lit by
the scene's lights and SH environment. No network: the honest reference the learnt materials of
glTF files are compared with, and what ``inshade render|view|info FILE.glb`` draws.

``scene_data(path)`` makes the scene a glTF file opens as (``Technique.opens``): the file as the
mesh (its normals, tangents, materials; geometry/gltf.py), an orbit camera framing its bounds, and
the views of ``VIEWS`` (the shaded result or one material channel). Its first look is the one glTF
viewers share (the Khronos Sample Viewer, three.js's): a neutral environment, Khronos PBR Neutral
tone mapping, exposure 1; two point lights scaled to the file's size are there to turn on
(``lights``). The look before that is ``--set sky=studio --set lights=2 --set tonemap=none``.
"""
from pathlib import Path

import numpy as np

from inshade.scene.tonemap import TONEMAPS
from inshade.technique import Choice, ProgramSpec, Technique

PROGRAM = "passes/gltf_pbr.frag"
# u_gltf_view's values in index order (GLTF_VIEW_* in the pass, from <choices>)
VIEWS = ("shaded", "base_color", "normal", "metallic", "roughness", "occlusion", "emissive")
SKIES = ["neutral", "studio", "sunset", "overcast", "noon"]


def scene_data(path) -> dict:
    """scene.json data for a glTF file (a SceneError naming the file and field if it cannot be read)."""
    from inshade.geometry.gltf import GltfError, load_gltf
    from inshade.scene.description import SceneError

    path = Path(path)
    try:
        asset = load_gltf(path)
    except GltfError as exc:
        raise SceneError(str(exc)) from None
    lo, hi = asset.mesh.bounds
    centre = (lo + hi) / 2.0
    radius = max(float(np.linalg.norm(hi - lo)) / 2.0, 1e-6)
    light = lambda offset, power: {"type": "point", "position": (centre + radius * np.array(offset)).tolist(),  # noqa: E731
                                   "intensity": power * radius * radius}
    return {"format": "inshade.scene", "version": 1, "name": path.stem,
            "title": f"{path.name}: glTF reference shading", "program": PROGRAM, "size": [512, 512],
            "networks": [], "mesh": path.name,
            "camera": {"type": "orbit", "fov_y": 40.0, "target": centre.tolist(), "distance": 3.0 * radius,
                       "yaw": 30.0, "pitch": -20.0},
            "lights": [light((2.0, 2.5, 2.0), 4.0), light((-2.5, 1.0, 1.5), 1.5)],
            "environment": {"sky": "neutral", "rotation": 0.0, "degree": 3},
            "display": {"mode": "final", "modes": ["final"], "split": 0.5},
            "settings": {
                "exposure": {"type": "float", "default": 1.0, "min": 0.0, "max": 8.0, "uniform": "u_exposure",
                             "label": "exposure"},
                "view": {"type": "choice", "default": "shaded", "choices": list(VIEWS), "uniform": "u_gltf_view",
                         "label": "view (shaded, or one material channel)"},
                "tonemap": {"type": "choice", "default": "pbr_neutral", "choices": list(TONEMAPS),
                            "present": "u_tonemap", "label": "tone mapping"},
                "lights": {"type": "int", "default": 0, "min": 0, "max": 2, "uniform": "u_light_count",
                           "label": "point lights"},
                "sky": {"type": "choice", "default": "neutral", "choices": SKIES, "environment": "sky",
                        "label": "environment"},
                "env_intensity": {"type": "float", "default": 1.0, "min": 0.0, "max": 8.0,
                                  "environment": "intensity", "label": "env intensity"},
                "env_rotation": {"type": "float", "default": 0.0, "min": -180.0, "max": 180.0,
                                 "environment": "rotation", "label": "env rotation (deg)"}},
            "notes": "; ".join(asset.notes)}


TECHNIQUE = Technique(
    name="gltf_pbr",
    summary="a glTF 2.0 asset with the spec's reference PBR shading (no network)",
    programs=(ProgramSpec(PROGRAM, geometry="mesh", mesh_attributes=("materials",), networks=False,
                          choices=(Choice("u_gltf_view", "GLTF_VIEW", VIEWS),)),),
    shaders=Path(__file__).resolve().parent / "shaders",
    opens={".glb": scene_data, ".gltf": scene_data},
)
