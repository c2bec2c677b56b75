"""The scene of a UV-free material learnt from a glTF file, and its render metrics.

The scene draws the copied file (``"mesh"``: its normals, tangents, materials) with
passes/mesh_uvfree_gltf.frag: the reference is the file's own material (lib/gltf_material, what
``inshade render FILE.glb`` draws), the network the same surface with the decoded channels put in,
so both go through one BRDF and differ only by what was learnt. Camera, lights and environment
are the ones the file opens with as a scene of its own (``Technique.opens`` for its suffix), so the
reference side is that render. ``render_metrics`` renders both views through the GL runtime at the
scene's camera. numpy + the runtime; no torch.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from inshade.lit_settings import lit_settings
from inshade.metrics import psnr, srgb_oetf
from inshade.scene.builder import choice_setting, display_modes, float_setting, network, scene_json
from inshade.scene.labels import split_labels

PROGRAM = "passes/mesh_uvfree_gltf.frag"


def scene_description(name: str, mesh: str, source_name: str, folder: Path, bundle: str, config: str,
                      channels) -> dict:
    from inshade import technique

    from . import ERROR_SCALE, GLTF_CHANNEL_VIEWS, GLTF_VIEWS

    opened = technique.opener(Path(mesh).suffix)(folder / mesh)
    sky = opened["environment"].get("sky", "studio")
    return scene_json(
        name, f"UV-free neural material of {source_name} ({config}): hashed per-triangle features + MLP "
              f"decoding {', '.join(channels)}",
        PROGRAM, opened["size"],
        networks=[network(bundle, "mat")],
        mesh=mesh,
        camera=opened["camera"], lights=opened["lights"], environment=opened["environment"],
        display=display_modes(),
        labels=split_labels("reference", "decoded"),
        settings={
            **lit_settings(sky),
            "view": choice_setting("split", GLTF_VIEWS, "view (split: left the file's material, right the network's)",
                                   uniform="u_uvg_view"),
            "channel": choice_setting("shaded", GLTF_CHANNEL_VIEWS,
                                      "shaded, or one material channel as the shader sees it", uniform="u_uvg_channel"),
            "lights": opened["settings"]["lights"],
            "tonemap": opened["settings"]["tonemap"],
            "env_intensity": opened["settings"]["env_intensity"],
            "error_scale": float_setting(ERROR_SCALE, 1.0, 64.0, "error view: |network - reference| x",
                                         uniform="u_uvg_error_scale"),
        },
        notes=f"the decoder outputs {', '.join(channels)}; every other material input (alpha, ior, KHR lobes) "
              "is the file's; the mesh's uv feed only the reference, the decoder reads the visibility buffer",
    )


def display_psnr(test: np.ndarray, ref: np.ndarray, mask: np.ndarray) -> float:
    """PSNR over the mesh's pixels of display values (linear clamped to [0, 1], sRGB-encoded, 8-bit)."""
    a = np.round(srgb_oetf(np.clip(test[..., :3], 0, 1)) * 255.0)
    b = np.round(srgb_oetf(np.clip(ref[..., :3], 0, 1)) * 255.0)
    return psnr(a, b, 255.0, mask=mask)


def render_views(folder, views=("reference", "decoded"), size=None, ctx=None) -> tuple[dict, np.ndarray]:
    """({view: linear RGBA [H, W, 4], image orientation}, mesh coverage [H, W]) at the scene's camera."""
    from inshade.runtime.render import read_rgba
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import load_scene

    scene = load_scene(folder)
    w, h = size or scene.size
    r = SceneRenderer(scene, ctx)
    try:
        camera = scene.make_camera()
        out = {}
        for view in views:
            r.set_setting("view", view)
            out[view] = read_rgba(r.render_network(camera, w, h)).copy()
        covered = r.gbuffer.read()[0][..., 3] == 1.0
    finally:
        r.release()
    return out, covered[::-1]   # G-buffer rows run from the bottom: as the images


def render_metrics(folder) -> dict:
    """Network vs reference at the scene's camera and size, over the mesh's pixels."""
    views, covered = render_views(folder)
    ref, net = views["reference"], views["decoded"]
    return {"render_psnr_vs_reference": round(display_psnr(net, ref, covered), 3),
            "render_psnr_linear": round(psnr(net[..., :3], ref[..., :3], mask=covered), 3),
            "render_size": list(ref.shape[1::-1]), "covered_pixels": int(covered.sum())}
