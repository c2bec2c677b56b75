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

from inshade.scene.builder import (choice_setting, display_modes, exposure_setting, float_setting, int_setting,
                                    orbit, point_light, scene_json, sky)
from inshade.scene.tonemap import TONEMAPS
from inshade.technique import Choice, ProgramSpec, Technique, folder_fields

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

    def light(offset, power):
        return point_light((centre + radius * np.array(offset)).tolist(), power * radius * radius)

    return scene_json(
        path.stem, f"{path.name}: glTF reference shading", PROGRAM, (512, 512),
        networks=[], mesh=path.name,
        camera=orbit(centre.tolist(), 3.0 * radius, 30.0, -20.0),
        lights=[light((2.0, 2.5, 2.0), 4.0), light((-2.5, 1.0, 1.5), 1.5)],
        environment=sky("neutral", degree=3),
        display=display_modes(),
        settings={
            "exposure": exposure_setting(),
            "view": choice_setting("shaded", VIEWS, "view (shaded, or one material channel)", uniform="u_gltf_view"),
            "tonemap": choice_setting("pbr_neutral", TONEMAPS, "tone mapping", present="u_tonemap"),
            "lights": int_setting(0, 0, 2, "point lights", uniform="u_light_count"),
            "sky": choice_setting("neutral", SKIES, "environment", environment="sky"),
            "env_intensity": float_setting(1.0, 0.0, 8.0, "env intensity", environment="intensity"),
            "env_rotation": float_setting(0.0, -180.0, 180.0, "env rotation (deg)", environment="rotation")},
        notes="; ".join(asset.notes))


TECHNIQUE = Technique(
    name="gltf_pbr",
    summary="a glTF 2.0 asset with the spec's reference PBR shading (no network)",
    programs=(ProgramSpec(PROGRAM, geometry="mesh", mesh_attributes=("materials",), networks=False,
                          choices=(Choice("u_gltf_view", "GLTF_VIEW", VIEWS),)),),
    **folder_fields(__name__, shaders=True),
    opens={".glb": scene_data, ".gltf": scene_data},
)
