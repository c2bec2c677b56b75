"""three.js as a peer renderer of glTF files: the file drawn by three.js r187 (npm ``three``, pinned in
tests/gltf_tools/package.json) in headless Chromium with the camera, size and point lights ``inshade
render`` gives the same file, so inshade's glTF reference shading (the spec's appendix B BRDF) can be
held against three.js's ``MeshStandardMaterial`` / ``MeshPhysicalMaterial``.

- ``three_render(browser, glb, w, h, ...)``: tests/gltf_tools/three_render.html served by
  ``inshade.web.browser.serve``; returns three.js's linear float render and its 8-bit sRGB canvas.
- ``inshade_render(glb, w, h, ...)``: inshade's linear float render of the same file and its coverage.
- ``coverage_iou`` / ``covered_psnr``: how the two compare.

Conventions checked here and by tests/web/test_three_peer.py:

- Matrices: inshade's cameras give pyrr matrices in the row-vector convention (``p_row @ view``), so
  ``view.ravel()`` in C order is the column-major array ``Matrix4.fromArray`` takes (the transpose of
  the column-vector matrix, read column by column). Both use OpenGL's clip space (z in [-1, 1]); the
  page checks that the view matrix's inverse puts the camera at ``camera.eye()``.
- Light units: inshade's point light of intensity I adds ``brdf * n.l * I / d^2`` (shaders/lib/lights.glsl,
  lib/gltf_material.glsl ``gltf_shade``); three.js since r155 (physically based units, no legacy
  lights) adds ``brdf * n.l * I / max(d^2, 0.01)`` for ``PointLight(color, I, distance=0, decay=2)``
  (I in candela). The same number goes to both; the lights are white.
- Images: both arrays are returned in image orientation (row 0 = top); three's alpha is its coverage
  (cleared to transparent black), inshade's coverage comes from its normal view under no environment.
"""
from __future__ import annotations

import base64
import json
from pathlib import Path

import numpy as np

from inshade.web.browser import BrowserError, serve

TOOLS = Path(__file__).resolve().parent / "gltf_tools"
PAGE = "three_render.html"
# inshade settings for "point lights only, linear": no environment light, no tone mapping (the float
# image is linear either way; tonemap only makes the PNG follow), both point lights
PUNCTUAL = {"env_intensity": 0.0, "tonemap": "none", "lights": 2}
ENVIRONMENTS = ("none", "room")
TONE_MAPPINGS = ("none", "neutral")
PSNR_PEAK = 1.0   # covered_psnr: linear values clipped to [0, 1], so the peak is 1.0
# three_render.mjs PATCHES: three.js r187's departures from the glTF spec's appendix B (as inshade shades
# it) that its shader chunks can be edited out of, one each, to measure what each costs
THREE_PATCHES = ("no_multiscatter", "no_geometry_roughness", "coat_fresnel_nv", "sheen_alpha_linear")


def scene_dict(glb_path) -> dict:
    """The scene data ``inshade render FILE.glb`` opens the file as (techniques/gltf_pbr scene_data)."""
    from inshade.techniques.gltf_pbr import scene_data

    return scene_data(Path(glb_path))


def setting_value(scene: dict, settings: dict | None, name: str):
    """A setting's value as inshade resolves it: the caller's, else the scene's default."""
    settings = settings or {}
    if name in settings:
        return settings[name]
    return scene["settings"][name]["default"]


def camera_config(scene: dict, width: int, height: int) -> dict:
    """The scene's camera for three_render.html: view and projection as column-major 16-arrays
    (pyrr's row-vector matrices ravelled in C order), the eye, near and far."""
    from inshade.scene.camera import camera_from_dict

    camera = camera_from_dict(scene["camera"])
    view = np.asarray(camera.view_matrix(), np.float64)
    projection = np.asarray(camera.projection(width, height), np.float64)
    return {"view": view.ravel().tolist(), "projection": projection.ravel().tolist(),
            "position": np.asarray(camera.eye(), np.float64).tolist(), "near": camera.near, "far": camera.far}


def lights_config(scene: dict, settings: dict | None = None) -> list[dict]:
    """The point lights inshade shades with (the first ``lights`` of the scene's), white, in the units
    three.js's PointLight(color, intensity, 0, 2) takes (the same number: see the module notes)."""
    count = int(setting_value(scene, settings, "lights")) if "lights" in scene.get("settings", {}) \
        else len(scene["lights"])
    out = []
    for light in scene["lights"][:max(count, 0)]:
        if light.get("type", "point") != "point":
            raise ValueError(f"three_render: only point lights are mapped, not {light.get('type')!r}")
        out.append({"position": [float(x) for x in light["position"]], "intensity": float(light["intensity"]),
                    "color": [1.0, 1.0, 1.0]})
    return out


def three_render(browser, glb_path, width: int, height: int, *, settings: dict | None = None,
                 environment: str = "none", tone_mapping: str = "none", exposure: float = 1.0,
                 patches: tuple[str, ...] = (), scene: dict | None = None) -> dict:
    """The .glb drawn by three.js in ``browser`` (an ``inshade.web.browser.Browser``) with the camera and
    point lights inshade gives it (``settings`` as inshade would apply them: ``lights`` picks how many).
    ``environment``: "none" | "room" (RoomEnvironment through PMREMGenerator); ``tone_mapping``:
    "none" | "neutral" (NeutralToneMapping) and ``exposure`` for the canvas picture only (the float render
    is never exposed; inshade's ``exposure`` setting scales its float image, so pass it here too to compare
    pictures). ``patches``:
    for diagnosis, three.js's departures from the glTF spec to turn off (THREE_PATCHES).

    Returns {"linear": float32 [H, W, 4] (the FloatType render target: linear, never tone mapped,
    alpha = coverage), "srgb8": uint8 [H, W, 3] (the canvas: sRGB output, the tone mapping asked for),
    "renderer": the WebGL renderer string, "revision": three.js's, "warnings": three.js's warnings}."""
    if environment not in ENVIRONMENTS:
        raise ValueError(f"environment: {environment!r}? ({', '.join(ENVIRONMENTS)})")
    if tone_mapping not in TONE_MAPPINGS:
        raise ValueError(f"tone_mapping: {tone_mapping!r}? ({', '.join(TONE_MAPPINGS)})")
    scene = scene_dict(glb_path) if scene is None else scene
    config = {"glb": base64.b64encode(Path(glb_path).read_bytes()).decode("ascii"),
              "width": int(width), "height": int(height), **camera_config(scene, width, height),
              "lights": lights_config(scene, settings), "environment": environment,
              "toneMapping": tone_mapping, "exposure": float(exposure), "patches": list(patches)}
    with serve(TOOLS) as url:
        driver = browser.driver
        if not driver.current_url.startswith(url):   # a new server (port) each call: reload the page
            driver.get(url + PAGE)
        result = driver.execute_async_script(
            "const config = arguments[0], done = arguments[arguments.length - 1];"
            "(async () => {"
            "  for (let i = 0; i < 600 && typeof window.threeRender !== 'function'; ++i)"
            "    await new Promise((r) => setTimeout(r, 50));"
            "  if (typeof window.threeRender !== 'function') throw new Error('three_render.mjs did not load');"
            "  return await window.threeRender(config);"
            "})().then(done, (e) => done({error: String(e && e.stack || e)}));", config)
    if not isinstance(result, dict) or result.get("error"):
        console = [f"{e['level']}: {e['message']}" for e in driver.get_log("browser")]
        raise BrowserError(f"{Path(glb_path).name}: three_render failed: {(result or {}).get('error', result)}; "
                           f"console: {json.dumps(console[-10:])}")
    h, w = int(result["height"]), int(result["width"])
    linear = np.frombuffer(base64.b64decode(result["linear"]), np.float32).reshape(h, w, 4)[::-1].copy()
    srgb8 = np.frombuffer(base64.b64decode(result["srgb8"]), np.uint8).reshape(h, w, 4)[::-1, :, :3].copy()
    return {"linear": linear, "srgb8": srgb8, "renderer": result["renderer"], "revision": result["revision"],
            "warnings": list(result.get("warnings") or [])}


def inshade_render(glb_path, width: int, height: int, *, settings: dict | None = None) -> dict:
    """inshade's render of the .glb (``render_scene``, the scene ``inshade render`` opens) with
    ``settings`` (default PUNCTUAL: point lights only), and its coverage: the normal view under no
    environment, where every mesh pixel is 0.5 + 0.5 n (never black) and the background is black.
    Returns {"linear": float32 [H, W, 4] row 0 = top, "coverage": bool [H, W]}."""
    from inshade.runtime.headless import render_scene
    from inshade.scene.description import load_scene

    settings = dict(PUNCTUAL if settings is None else settings)
    scene = load_scene(Path(glb_path))
    missing = sorted(set(PUNCTUAL) - set(scene.settings))
    if missing:
        raise RuntimeError(f"{glb_path}: this inshade has no setting {', '.join(missing)} (needed to light a glTF "
                           "file by its point lights alone)")
    image, _ = render_scene(scene, width=width, height=height, settings=settings)
    normals, _ = render_scene(scene, width=width, height=height,
                              settings={**settings, "env_intensity": 0.0, "view": "normal"})
    return {"linear": image, "coverage": normals[..., :3].sum(-1) > 0.25}


def three_coverage(three: dict) -> np.ndarray:
    return three["linear"][..., 3] > 0.5


def erode(mask: np.ndarray, pixels: int = 1) -> np.ndarray:
    """Binary erosion by a (2 pixels + 1)^2 square: a pixel stays if all its 8-neighbours (within
    ``pixels``) are set; the image border counts as unset."""
    out = np.asarray(mask, bool)
    for _ in range(pixels):
        p = np.pad(out, 1, constant_values=False)
        h, w = out.shape
        out = np.logical_and.reduce([p[1 + dy:1 + dy + h, 1 + dx:1 + dx + w]
                                     for dy in (-1, 0, 1) for dx in (-1, 0, 1)])
    return out


def coverage_iou(a: np.ndarray, b: np.ndarray) -> float:
    """Intersection over union of two coverage masks (1.0 when both are empty)."""
    union = np.logical_or(a, b).sum()
    return 1.0 if union == 0 else float(np.logical_and(a, b).sum() / union)


def compared_pixels(cover_a: np.ndarray, cover_b: np.ndarray) -> np.ndarray:
    """The pixels both renderers cover, eroded by 1 pixel so silhouette edges do not count."""
    return erode(np.logical_and(cover_a, cover_b), 1)


def covered_psnr(a: np.ndarray, b: np.ndarray, mask: np.ndarray) -> float:
    """PSNR (dB) of two linear RGB images over ``mask``: values clipped to [0, 1], peak PSNR_PEAK = 1.0,
    the mean squared error over the masked pixels' three channels; inf when equal."""
    mask = np.asarray(mask, bool)
    if not mask.any():
        raise ValueError("covered_psnr: no pixel to compare")
    x = np.clip(np.asarray(a, np.float64)[..., :3][mask], 0.0, 1.0)
    y = np.clip(np.asarray(b, np.float64)[..., :3][mask], 0.0, 1.0)
    mse = float(np.mean((x - y) ** 2))
    return float("inf") if mse == 0.0 else 10.0 * np.log10(PSNR_PEAK ** 2 / mse)


def picture_stats(srgb8: np.ndarray, mask: np.ndarray) -> dict:
    """Over ``mask``'s pixels of an 8-bit sRGB picture: the mean colour (8-bit sRGB values), the mean
    relative luminance Y (Rec. 709 weights on the decoded, linear values) and Y's sRGB 8-bit level."""
    from inshade.scene.image_io import srgb_oetf

    c = np.asarray(srgb8, np.float64)[..., :3][np.asarray(mask, bool)] / 255.0
    linear = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    y = float((linear @ np.array([0.2126, 0.7152, 0.0722])).mean())
    return {"pixels": len(c), "mean_srgb8": [round(float(x), 1) for x in (255.0 * c).mean(0)],
            "mean_luminance": round(y, 4), "mean_luminance_srgb8": round(float(255.0 * srgb_oetf(np.array(y))), 1)}


def compare(browser, glb_path, width: int, height: int, *, settings: dict | None = None,
            patches: tuple[str, ...] = ()) -> dict:
    """inshade and three.js on one file, point lights only (PUNCTUAL unless ``settings``), linear:
    {"psnr": dB over compared_pixels, "iou": coverage IoU, "pixels": how many compared, "mean_abs":
    mean |inshade - three| per channel there, "mean_ratio": sum(three) / sum(inshade) there,
    "inshade", "three": the renders, "mask"}."""
    settings = dict(PUNCTUAL if settings is None else settings)
    ours = inshade_render(glb_path, width, height, settings=settings)
    theirs = three_render(browser, glb_path, width, height, settings=settings, patches=patches)
    cover = three_coverage(theirs)
    mask = compared_pixels(ours["coverage"], cover)
    a, b = ours["linear"][..., :3][mask], theirs["linear"][..., :3][mask]
    return {"psnr": covered_psnr(ours["linear"], theirs["linear"], mask), "iou": coverage_iou(ours["coverage"], cover),
            "pixels": int(mask.sum()), "mean_abs": np.abs(a - b).mean(0).tolist(),
            "mean_ratio": float(b.sum() / max(a.sum(), 1e-30)), "inshade": ours, "three": theirs, "mask": mask}


# one material a file ------------------------------------------------------------------------------------
def _ball(material: dict, *, tangents: bool = True, texture_sets: dict | None = None):
    """A GltfBuilder holding one uv sphere (radius 0.5) with ``material``, whose ``{"index": "<name>"}``
    texture references name tile_textures() images (or ``texture_sets``')."""
    from inshade.geometry import gltf_scenes
    from inshade.geometry.gltf_write import GltfBuilder
    from inshade.geometry.shapes import sphere

    b = GltfBuilder()
    images = {**gltf_scenes.tile_textures(), **(texture_sets or {})}
    made = {}

    def resolve(x):
        if isinstance(x, dict):
            out = {k: resolve(v) for k, v in x.items()}
            if isinstance(out.get("index"), str):
                name = out["index"]
                if name not in made:
                    made[name] = b.texture(b.image(images[name]))
                out["index"] = made[name]
            return out
        return [resolve(v) for v in x] if isinstance(x, list) else x

    mat = b.material(resolve(material))
    b.node(b.mesh([gltf_scenes._primitive(sphere(0.5, 32), mat, tangents=tangents)], "ball"), name="ball")
    return b


# name -> (what it exercises, material, tangents authored)
BALLS = {
    "base_color": ("a dielectric with a base colour texture", {
        "pbrMetallicRoughness": {"baseColorTexture": {"index": "base_color"}, "metallicFactor": 0.0,
                                 "roughnessFactor": 0.6}}, True),
    "metal_rough": ("metallic and roughness from a texture (metals and dielectrics, rough 0.25 .. 1)", {
        "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.7, 0.5, 1.0],
                                 "metallicRoughnessTexture": {"index": "metallic_roughness"}}}, True),
    "normal_map": ("a normal map with authored tangents", {
        "pbrMetallicRoughness": {"baseColorFactor": [0.6, 0.6, 0.6, 1.0], "metallicFactor": 0.0,
                                 "roughnessFactor": 0.5},
        "normalTexture": {"index": "normal", "scale": 1.0}}, True),
    "normal_map_no_tangents": ("the same normal map without tangents (MikkTSpace vs a screen-space frame)", {
        "pbrMetallicRoughness": {"baseColorFactor": [0.6, 0.6, 0.6, 1.0], "metallicFactor": 0.0,
                                 "roughnessFactor": 0.5},
        "normalTexture": {"index": "normal", "scale": 1.0}}, False),
    "emissive": ("an emissive texture over a dark dielectric", {
        "pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.2, 0.2, 1.0], "metallicFactor": 0.0,
                                 "roughnessFactor": 0.7},
        "emissiveTexture": {"index": "emissive"}, "emissiveFactor": [1.0, 1.0, 1.0]}, True),
    "clearcoat": ("KHR_materials_clearcoat: the showcase's car paint", {
        "pbrMetallicRoughness": {"baseColorFactor": [0.6, 0.03, 0.02, 1.0], "metallicFactor": 0.3,
                                 "roughnessFactor": 0.5},
        "extensions": {"KHR_materials_clearcoat": {"clearcoatFactor": 1.0, "clearcoatRoughnessFactor": 0.05}}}, True),
    "sheen": ("KHR_materials_sheen over a rough dielectric", {
        "pbrMetallicRoughness": {"baseColorFactor": [0.3, 0.15, 0.35, 1.0], "metallicFactor": 0.0,
                                 "roughnessFactor": 0.8},
        "extensions": {"KHR_materials_sheen": {"sheenColorFactor": [0.9, 0.8, 1.0], "sheenRoughnessFactor": 0.4}}},
        True),
    "anisotropy": ("KHR_materials_anisotropy: brushed metal, authored tangents", {
        "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.85, 0.8, 1.0], "metallicFactor": 1.0,
                                 "roughnessFactor": 0.45},
        "extensions": {"KHR_materials_anisotropy": {"anisotropyStrength": 0.8, "anisotropyRotation": 0.4}}}, True),
}


def ball_glb(name: str, folder) -> Path:
    """BALLS[name] written to ``folder/<name>.glb``."""
    _, material, tangents = BALLS[name]
    return _ball(material, tangents=tangents).write(Path(folder) / f"{name}.glb")
