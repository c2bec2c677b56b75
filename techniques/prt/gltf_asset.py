"""The PRT asset of a glTF file (``inshade train prt --gltf FILE``, techniques/prt/train.py):

- the file is copied into the asset as ``source.glb`` / ``source.gltf`` (geometry/gltf.py ``copy_gltf``), byte-identical
  (a ``.gltf``'s external buffers and images beside it, at the same relative paths): the scene's mesh;
- ``gltf_scene``: the mesh scene drawn by passes/mesh_prt_gltf.frag -- PRT with the albedo of the
  file's base colour next to the file's reference shading, a ``view`` setting (``GLTF_VIEWS``: prt |
  reference | split | albedo), notes saying what differs by design;
- ``gltf_previews_and_quality``: previews (PRT diffuse and glossy, the split view), the technique's
  quality over an orbit (twin.py ``quality_orbit``, its ground truth shaded with each pixel's albedo
  from the albedo view), and PRT against the reference at the scene's camera, both through the GL
  runtime (``reference``: PSNR / SSIM / MAE over the surface, diffuse).

numpy + the GL runtime; torch only through twin.py's quality measurement.
"""
from __future__ import annotations

import time
from pathlib import Path

from inshade.techniques.prt import GLTF_VIEWS

SOURCE = "source"
NOTES = ("view: prt (the transfer network's PRT shading with the file's base colour as albedo), reference "
         "(the file shaded by the glTF reference: the spec's BRDF, normal map, occlusion texture, emission), "
         "split (left reference, right PRT), albedo (the base colour PRT multiplies). They differ by design: "
         "PRT is diffuse (or Phong glossy) transfer of the environment with the shadows the mesh casts on "
         "itself, at the interpolated normal; the reference has the specular lobe, metal, normal map, "
         "occlusion texture and emission, and no cast shadows. Both are lit by the environment alone.")
PREVIEWS = (({"view": "prt", "shading": "diffuse"}, "preview.png"),
            ({"view": "prt", "shading": "glossy"}, "preview_glossy.png"),
            ({"view": "split", "shading": "diffuse"}, "preview_split.png"))


def gltf_scene(mesh_scene: dict, program: str) -> dict:
    """The glTF file's PRT scene from the mesh scene train.py writes for it (same camera, settings,
    environment): the glTF pass, its view setting and notes."""
    view = {"type": "choice", "default": "split", "choices": list(GLTF_VIEWS), "uniform": "u_prt_view",
            "label": "view (PRT, the glTF reference, or side by side)"}
    return {**mesh_scene, "program": program, "settings": {**mesh_scene["settings"], "view": view},
            "notes": NOTES}


def _render(renderer, camera, size: int, **settings):
    from inshade.runtime.render import read_rgba

    for name, value in settings.items():
        renderer.set_setting(name, value)
    return read_rgba(renderer.render_network(camera, size, size))


def compare_with_reference(scene, size: int, ctx=None, cache=None) -> dict:
    """PRT (diffuse) against the glTF reference at the scene's camera, both drawn by the GL
    runtime: twin.py ``image_metrics`` over the surface (``psnr``, ``mae``; ``psnr_image`` and
    ``ssim`` over the whole image, whose background is the same in both)."""
    from inshade.runtime.renderer import SceneRenderer
    from inshade.techniques.prt.twin import image_metrics

    renderer = SceneRenderer(scene, ctx, cache=cache)
    try:
        camera = scene.make_camera()
        prt = _render(renderer, camera, size, view="prt", shading="diffuse")
        reference = _render(renderer, camera, size, view="reference")
        covered = renderer.gbuffer.read()[0][::-1, :, 3] > 0       # image orientation
    finally:
        renderer.release()
    return {**image_metrics(prt, reference, covered), "size": size, "shading": "diffuse"}


def gltf_previews_and_quality(out: Path, views: int, size: int, dirs: int,
                              preview_size: int) -> tuple[dict, dict, dict]:
    """(quality, {"reference": PRT vs the reference}, seconds) of the asset folder ``out``."""
    from inshade.runtime.context import shared_context
    from inshade.runtime.headless import render_scene, save_render
    from inshade.runtime.programs import ProgramCache
    from inshade.scene.description import load_scene
    from inshade.techniques.prt.twin import quality_orbit

    scene = load_scene(out)
    ctx = shared_context()
    cache = ProgramCache(ctx)         # one compile of the pass for every step
    start = time.perf_counter()
    for settings, fname in PREVIEWS:
        image, info = render_scene(scene, settings=settings, ctx=ctx, cache=cache)
        save_render(image, info, out / fname)
        (out / (fname + ".json")).unlink(missing_ok=True)  # the sidecar names local paths
    times = {"preview_seconds": time.perf_counter() - start}
    start = time.perf_counter()
    reference = compare_with_reference(scene, preview_size, ctx, cache)
    times["reference_seconds"] = time.perf_counter() - start
    start = time.perf_counter()
    quality = quality_orbit(scene, n_views=views, size=size, n_dirs=dirs, ctx=ctx, cache=cache, progress=None,
                            albedo_view=("view", "prt", "albedo"))
    times["quality_seconds"] = time.perf_counter() - start
    for mode in ("diffuse", "glossy"):
        quality[mode].pop("views", None)
    return quality, {"reference": reference}, times
