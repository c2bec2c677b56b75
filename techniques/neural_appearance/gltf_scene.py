"""The scene of a neural glTF material and how close it comes to the file's own shading.

- ``scene_description``: scene.json drawing passes/mesh_neural_appearance_gltf.frag over the asset's
  copy of the file: the lights and sky ``inshade render FILE.glb`` shows the file with (the opener
  the registry holds for the suffix), its camera turned to frame the learnt material (the whole
  file: bookmark ``file``), the views of ``GLTF_VIEWS`` (split: left the reference, right the neural
  material), the lighting of ``GLTF_LIGHTING`` and the technique's settings.
- ``render_metrics``: through the GL runtime, at the scene's camera and size, the neural material's
  pixels against the reference's (lib/gltf_material ``gltf_surface`` + ``gltf_shade``) on the learnt
  material's pixels: PSNR of display values (linear x exposure 1, clamped, sRGB-encoded, 8 bit),
  lights only (the network's error alone) and shaded (with the environment: the reference's split
  sum against the neural material's Monte Carlo estimate), per decoder.

numpy + the runtime; no torch.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

SIZE = (384, 384)


def scene_description(out: Path, source: str, material: int, material_name: str, bounds) -> dict:
    """scene.json data of the asset in ``out`` whose mesh is ``out / source``; ``bounds``: the learnt
    material's world-space box (lo, hi)."""
    from inshade.scene.builder import choice_setting, display_modes, network, requires, scene_json
    from inshade.scene.labels import split_labels
    from inshade.technique import opener

    from . import GLTF_LIGHTING, GLTF_PROGRAM, GLTF_VIEWS, NETWORKS
    from .scene_settings import pyramid_settings, sampling_settings

    opens = opener(Path(source).suffix)
    if opens is None:
        raise ValueError(f"{source}: no technique draws {Path(source).suffix} files (the glTF reference pass)")
    base = opens(Path(out) / source)
    settings = {k: v for k, v in base["settings"].items()
                if k in ("exposure", "tonemap", "lights", "sky", "env_rotation", "env_intensity")}
    # lit as its renders were measured: the studio sky (a brighter sky is more Monte Carlo noise in the
    # environment's share) and the point lights its "lights" view needs, which the file's own scene
    # leaves off
    settings["lights"] = {**settings["lights"], "default": len(base["lights"])}
    settings["sky"] = {**settings["sky"], "default": "studio"}
    lo, hi = (np.asarray(b, np.float64) for b in bounds)
    # as the opener frames the file (3 bounding radii away), around the learnt material only
    camera = {**base["camera"], "target": ((lo + hi) / 2).tolist(),
              "distance": 3.0 * max(float(np.linalg.norm(hi - lo)) / 2.0, 1e-6)}
    return scene_json(
        Path(out).name,
        f"neural appearance: {Path(source).name} material {material} ({material_name}), "
        "glTF reference | latent pyramid + MLP decoder",
        GLTF_PROGRAM, SIZE,
        networks=[network(folder, prefix) for folder, prefix in NETWORKS],
        mesh=source,
        camera=camera, bookmarks={"file": base["camera"]},
        lights=base["lights"], environment={**base["environment"], "sky": "studio"},
        display=display_modes(),
        labels=split_labels("reference", "neural"),
        settings={
            **settings,
            "view": choice_setting("split", GLTF_VIEWS, "view (split: left reference, right neural)",
                                   uniform="u_na_view"),
            "lighting": choice_setting("shaded", GLTF_LIGHTING,
                                       "lighting: shaded = lights + environment + emission (neural: Monte Carlo, "
                                       "accumulated) | lights = lights + emission", uniform="u_na_lighting"),
            "decoder": choice_setting(32, [16, 32, 64], "decoder: 16 = 2x16, 32 = 2x32, 64 = 3x64",
                                      define="NA_DECODER"),
            **sampling_settings("BRDF sampling (environment)"),
            **pyramid_settings(),
        },
        requires=requires(),
        notes=f"material {material} is neural, the others are the file's; shaded lighting accumulates "
              "(inshade render --spp N)" + (f"; {base['notes']}" if base.get("notes") else ""),
    )


def display8(image: np.ndarray) -> np.ndarray:
    """Linear RGB -> the 8-bit sRGB values a PNG of it holds (exposure 1)."""
    from inshade.metrics import srgb_oetf

    return np.round(srgb_oetf(np.clip(image[..., :3], 0.0, 1.0)) * 255.0)


def learnt_pixels(gbuffer, material: int) -> np.ndarray:
    """[H, W] bool, image orientation: pixels whose surface is the learnt material (MeshGBuffer.read())."""
    position, _normal, uv = gbuffer[:3]
    mask = (position[..., 3] != 0) & (np.rint(uv[..., 2]) == material)
    return mask[::-1]


def render_metrics(out: Path, material: int, spp: int, decoders=(32,)) -> dict:
    """PSNR of the neural views against the reference at the scene's camera and size (see the module
    docstring): ``{"render": {...}}``."""
    from inshade.metrics import psnr
    from inshade.runtime.context import gl_info, shared_context
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import load_scene

    scene = load_scene(out)
    width, height = scene.size
    camera = scene.make_camera()
    started = time.perf_counter()
    r = SceneRenderer(scene, settings={"view": "reference", "lighting": "lights", "decoder": decoders[0]})
    views = {}
    try:
        for lighting in ("lights", "shaded"):
            r.set_setting("lighting", lighting)
            r.set_setting("view", "reference")
            r.accumulate(camera, width, height, 1)
            views[("reference", lighting)] = display8(r.read("network"))
            if lighting == "lights":
                mask = learnt_pixels(r.gbuffer.read(), material)
        for decoder in decoders:
            r.set_setting("decoder", decoder)
            r.set_setting("view", "neural")
            for lighting in ("lights", "shaded"):
                r.set_setting("lighting", lighting)
                r.accumulate(camera, width, height, spp)
                views[(decoder, lighting)] = display8(r.read("network"))
    finally:
        r.release()
    result = {"size": [width, height], "spp": spp, "learnt_pixels": int(mask.sum()),
              "gl_renderer": gl_info(shared_context())["renderer"],
              "seconds": round(time.perf_counter() - started, 1)}
    for decoder in decoders:
        name = {16: "2x16", 32: "2x32", 64: "3x64"}[decoder]
        for lighting in ("lights", "shaded"):
            value = psnr(views[(decoder, lighting)], views[("reference", lighting)], 255.0, mask=mask) \
                if mask.any() else None
            result[f"psnr_{lighting}_{name}"] = None if value is None else round(value, 3)
    return {"render": result}
