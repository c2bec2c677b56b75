"""The asset of a user's scene file (``inshade train appearance_prefilter --scene FILE``, train.py):

- the file copied into the asset as ``source.<ext>`` (geometry/gltf.py ``copy_gltf``), byte-identical (a ``.gltf``'s
  external buffers and images beside it, at the same relative paths);
- ``cameras``: an orbit camera framing the file's bounds (as ``inshade render FILE.glb`` frames
  it), in the file's coordinates and the same camera in the voxels' unit box;
- ``write_user_scene``: ``reference.exr`` (the full geometry ray traced with the bake's per-face
  material, reference.py, at the box camera: the same rays as the world camera's) and scene.json --
  a glTF file's draws the file as its mesh with passes/appearance_prefilter_gltf.frag (``view``
  prefiltered | reference | split ...), a mesh's is the procedural scenes' pass at the box camera;
- ``asset_geometry``: an asset's PrefilterScene (its copy of the file) and its camera in the unit
  box, for the bench;
- ``compare_with_references``: the prefiltered render (view prefiltered, the scene's defaults)
  against the ray-traced reference and, for a glTF file, against the file's reference shading
  (view reference), at the scene's camera and size through the GL runtime: PSNR of linear RGB
  clipped to [0, 1] over the whole image and over the pixels the file's mesh covers.

numpy + the GL runtime; no torch.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from inshade.files import atomic_write
from inshade.geometry.gltf import copy_gltf

from . import GLTF_PROGRAM, GLTF_VIEWS

SOURCE = "source"
YAW, PITCH, FOV_Y = 30.0, -20.0, 35.0    # the procedural scenes' view angles (train.py CAMERA)
DISTANCE = 3.0                            # x the bounding sphere's radius
GLTF_NOTES = ("view: prefiltered (the voxels, marched at the footprint's scale), reference (the file shaded by "
              "the glTF reference: the spec's BRDF with its textures), split (left reference, right prefiltered); "
              "display split / error: prefiltered against reference.exr, the file's geometry ray traced with the "
              "voxels' per-face material. They differ by design: the voxels carry one material per face (no "
              "normal, occlusion or emissive textures, no clearcoat, sheen or anisotropy), the bake's BRDF "
              "(Burley diffuse + GGX) and sun shadows; the reference has none of the shadows.")


def cameras(user) -> tuple[dict, dict]:
    """(world camera, box camera) framing a UserScene's bounds."""
    lo, hi = (np.asarray(b, np.float64) for b in user.bounds)
    centre = 0.5 * (lo + hi)
    radius = max(float(np.linalg.norm(hi - lo)) / 2.0, 1e-6)
    world = {"type": "orbit", "fov_y": FOV_Y, "target": centre.tolist(), "distance": DISTANCE * radius,
             "yaw": YAW, "pitch": PITCH}
    scale = float(user.world["scale"])
    box_target = (centre - np.asarray(user.world["centre"], np.float64)) * scale + 0.5
    return world, {**world, "target": box_target.tolist(), "distance": DISTANCE * radius * scale}


def write_user_scene(out: Path, settings: dict, user, base: dict, spp: int) -> dict:
    """reference.exr and scene.json of a user's scene file; ``base``: the procedural scene.json of
    the run (train.py scene_description: lights, environment, size, settings); returns the scene."""
    from inshade.codegen.sdf import environment_sh
    from inshade.scene.image_io import write_exr

    from .reference import render_reference

    source = copy_gltf(Path(settings["scene"]), out, SOURCE)
    world, box = cameras(user)
    sun, sky = base["lights"][0], base["environment"]
    image = render_reference(user.scene, box, tuple(base["size"]), spp=spp, sun_dir=sun["direction"],
                             sun_radiance=sun["intensity"],
                             env_sh=environment_sh(sky["sky"], sky["rotation"], sky["degree"]), seed=settings["seed"])
    write_exr(out / base["reference"]["image"], image)
    lo, hi = settings["scales"]
    scene = {**base, "title": f"Deep appearance prefiltering: {Path(settings['scene']).name}, scales {lo}..{hi} "
                              "(voxel latents + coverage/albedo/phase decoders)",
             "camera": box, "notes": "; ".join([base["notes"], *user.notes])}
    if user.kind == "gltf":
        own = {k: v for k, v in base["settings"].items() if k != "distance"}   # the camera itself moves here
        own["view"] = {**own["view"], "default": "split", "choices": list(GLTF_VIEWS)}
        scene.update(program=GLTF_PROGRAM, mesh=source, camera=world, settings=own,
                     notes="; ".join([GLTF_NOTES, *user.notes]))
    atomic_write(out / "scene.json", json.dumps(scene, indent=2) + "\n")
    return scene


def asset_geometry(folder: Path, settings: dict, camera):
    """(PrefilterScene, camera in the unit box) of an asset folder whose metrics.json recorded
    ``settings``: a procedural scene rebuilt, or the asset's copy of the file with ``camera`` (the
    scene's) taken into the box when the scene draws the file in its own coordinates."""
    from inshade.scene.camera import camera_from_dict

    from .scene import build_scene
    from .user_scene import is_file_scene, load_user_scene

    if not is_file_scene(settings["scene"]):
        return build_scene(settings["scene"], settings["detail"]), camera
    user = load_user_scene(folder / (SOURCE + Path(settings["scene"]).suffix.lower()))
    if user.kind != "gltf":
        return user.scene, camera
    scale, centre = float(user.world["scale"]), np.asarray(user.world["centre"], np.float64)
    data = camera.to_dict()
    if data.get("type") != "orbit":
        raise ValueError(f"{folder}: camera: the unit box's camera is made from an orbit camera, "
                         f"got {data.get('type')!r}")
    target = (np.asarray(data["target"], np.float64) - centre) * scale + 0.5
    return user.scene, camera_from_dict({**data, "target": target.tolist(),
                                         "distance": float(data["distance"]) * scale})


def _psnr(a: np.ndarray, b: np.ndarray, mask=None) -> float:
    from inshade.metrics import psnr

    return round(psnr(np.clip(a[..., :3], 0.0, 1.0), np.clip(b[..., :3], 0.0, 1.0), mask=mask), 3)


def compare_with_references(out: Path, ctx=None, cache=None) -> dict:
    """{"traced": {...}, "gltf": {...} (a glTF file's)}: PSNR of the prefiltered render against each
    reference at the scene's camera and size (``psnr``: the whole image; ``psnr_surface``: the pixels
    the file's mesh covers, from the G-buffer of a glTF scene)."""
    from inshade.runtime.render import read_rgba
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import load_scene
    from inshade.scene.image_io import read_exr

    scene = load_scene(out)
    width, height = scene.size
    renderer = SceneRenderer(scene, ctx, cache=cache)
    try:
        camera = scene.make_camera()
        renderer.set_setting("view", "prefiltered")
        prefiltered = read_rgba(renderer.render_network(camera, width, height))
        reference, covered = None, None
        if renderer.gbuffer is not None:
            covered = renderer.gbuffer.read()[0][::-1, :, 3] > 0     # image orientation
            renderer.set_setting("view", "reference")
            reference = read_rgba(renderer.render_network(camera, width, height))
    finally:
        renderer.release()
    traced = read_exr(scene.reference.image)
    result = {"traced": {"psnr": _psnr(prefiltered, traced)}, "size": [width, height]}
    if reference is not None:
        result["traced"]["psnr_surface"] = _psnr(prefiltered, traced, covered)
        result["gltf"] = {"psnr": _psnr(prefiltered, reference), "psnr_surface": _psnr(prefiltered, reference, covered),
                          "surface_pixels": int(covered.sum())}
    return result
