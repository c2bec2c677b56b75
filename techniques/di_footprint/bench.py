"""`inshade bench di_footprint`: the DI footprint-aware sampler (no mip chain) against GL's own
sampling of the uncompressed texture, on a tiled ground plane seen at grazing angles.

One view (``passes/footprint_plane.frag``, camera models/footprint_sampler.py CAMERA), five renders
through the GL driver:

- ``di``: the DI footprint sampler (generated GLSL, exact LUT path; ``di_fast``: hardware-filtered);
- ``trilinear``: GL_LINEAR_MIPMAP_LINEAR of the RGB8 texture with its mip chain;
- ``anisotropic``: the same texture with max anisotropy 16 (or the driver's maximum);
- ``bilinear``: no mips, bilinear of the base level (what the network replaces without a chain: aliasing);
- ``explicit_lod``: GL trilinear at the shader's own LOD (log2 footprint + log2 N), the footprint
  rule the network is trained with.

Ground truth: the same view supersampled ``--ss`` x ``--ss`` per pixel (rays through a regular
sub-pixel grid, bilinear of the base level with GL_REPEAT, averaged), computed in float64 numpy
independently of GL. Texels are averaged in sRGB-encoded space like every mode here (RGB8 mips
and the emulated sampler filter encoded values). PSNR is sRGB 8-bit over the pixels whose every
sub-sample hits the plane. Also reported: the DI sampler vs the emulated trilinear sampler
(torch) on held-out (uv, footprint) samples and per LOD, the DI-vs-torch parity of the exact
path on this view, the bytes of each mode, and GL_RENDERER.

Writes ``di_footprint.json``, ``.md``, ``.png`` (PSNR per mode, PSNR per LOD) and
``di_footprint_views.png`` (the modes side by side with the ground truth) into ``--out``.
``--quick``: a 32x32 texture trained 60 steps, a 96x48 view (tests / smoke runs).
"""
from __future__ import annotations

import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from inshade.bench.contract import Bench, option, sized
from inshade.bench.entry import Claim, claim_row
from inshade.bench.harness import (BenchError, atomic_path, label_axes, machine, machine_markdown, matplotlib_pyplot,
                                   portable_command, portable_path, save_figure, write_report)
from inshade.metrics import psnr, srgb_eotf, srgb_oetf
from inshade.techniques.di_footprint import MODES

DEFAULT_OUT = "bench-out/footprint"
DEFAULT_ASSET = "trained/di_footprint"
GL_MODES = tuple(m for m in MODES if m != "di")   # the GL samplers the DI one is compared with
MAX_ANISOTROPY = 16.0


@dataclass
class Settings:
    out: str = option(DEFAULT_OUT, f"output folder (default {DEFAULT_OUT})")
    asset: str = option(DEFAULT_ASSET, "a di_footprint asset folder to evaluate (default %(default)s; trained here "
                                       "if missing)")
    width: int = option(512)
    height: int = option(256)
    ss: int = option(16, "ground-truth sub-samples per pixel axis (default 16)")
    tile: float | None = option(None, "world units per tile (default: the scene's)")
    extent: float | None = option(None, "plane half-size, world units (default: the scene's)")
    steps: int | None = option(None, "training steps when the asset is trained here")
    quick: bool = option(False, "tiny run: 32x32 texture, 60 steps, 96x48 view")


def _errors() -> tuple:
    from inshade.models.footprint_sampler import FootprintError

    return BenchError, FootprintError


# ---------------------------------------------------------------------------------------------
# GL renders

def write_texture(path: Path, image_tex: np.ndarray) -> Path:
    """The sRGB-encoded texture (texture orientation, row 0 at v ~ 0) as the 8-bit RGB PNG a scene's
    "textures" entry binds (image orientation; the values exactly, no colour conversion)."""
    from PIL import Image

    data = np.rint(np.clip(image_tex, 0, 1) * 255).astype(np.uint8)
    if data.shape[2] == 1:
        data = np.repeat(data, 3, -1)
    Image.fromarray(np.ascontiguousarray(data[::-1]), "RGB").save(path)
    return path


class PlaneRenderer:
    """passes/footprint_plane.frag for one bundle and texture, drawn by the runtime's SceneRenderer
    over the asset's scene with the GL modes (train.py ``scene_dict(gl_modes=True)``: the texture as
    RGB8 + GL-built mips, GL_REPEAT, bound as u_texture and, anisotropic, u_texture_aniso):
    ``render(mode, camera, w, h, tile, extent)`` -> (linear RGBA [H, W, 4], DI inputs [H, W, 4]),
    both in image orientation (the program's two attachments)."""

    def __init__(self, ctx, bundle, image_tex: np.ndarray, lut_filter: str = "exact"):
        import tempfile

        from inshade.techniques.di_footprint import train as fp
        from inshade.runtime.renderer import SceneRenderer
        from inshade.scene.description import load_scene

        self.ctx, self.bundle = ctx, bundle
        # the scene is read from a folder (scene.json, bundle.json, texture.png) that only lives
        # while the renderer is built: the textures are uploaded and the bundle given in memory
        with tempfile.TemporaryDirectory(prefix="inshade-footprint-") as tmp:
            folder = Path(tmp)
            path = bundle.path
            bundle.save(folder)
            bundle.path = path   # save() points the bundle at the folder, which goes away
            write_texture(folder / "texture.png", image_tex)
            output = bundle.outputs[0].name
            scene = fp.scene_dict(folder.name, "footprint bench", output, gl_modes=True)
            (folder / "scene.json").write_text(json.dumps(scene))
            self.scene = load_scene(folder)
            self.renderer = SceneRenderer(self.scene, ctx, bundles=[bundle], settings={"lut_filter": lut_filter})

    def render(self, mode: str, camera, width: int, height: int, tile: float, extent: float):
        r = self.renderer
        r.set_setting("mode", MODES[mode])
        r.set_setting("tile", float(tile))
        r.set_setting("extent", float(extent))
        r.render_network(camera, width, height)
        return r.read("network", 0), r.read("network", 1)

    def release(self):
        self.renderer.release()
        self.renderer.cache.release()


# ---------------------------------------------------------------------------------------------
# ground truth (numpy, float64, independent of GL)

def camera_rays(camera, width: int, height: int, offsets=((0.5, 0.5),)):
    """Ray origin and directions [len(offsets), H, W, 3] (image orientation) through pixel
    positions (x + ox, y + oy) in GL window coordinates, as lib/footprint.glsl builds them."""
    u = camera.uniforms(width, height)
    inv = np.frombuffer(u["u_inv_view_proj"], np.float32).reshape(4, 4).astype(np.float64)  # row-vector form
    eye = np.asarray(u["u_eye"], np.float64)
    xs, ys = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64)[::-1])
    out = []
    for ox, oy in offsets:
        ndc = np.stack([(xs + ox) * 2.0 / width - 1.0, (ys + oy) * 2.0 / height - 1.0,
                        np.ones_like(xs), np.ones_like(xs)], -1)
        w = ndc @ inv
        d = w[..., :3] / w[..., 3:] - eye
        out.append(d / np.linalg.norm(d, axis=-1, keepdims=True))
    return eye, np.stack(out)


def plane_uv(eye, rd, tile: float, extent: float):
    """Tiled uv of the hits with y = 0 and the hit mask (lib/footprint.glsl footprint_plane_uv)."""
    t = eye[1] / np.maximum(-rd[..., 1], 1e-6)
    p = eye + rd * t[..., None]
    hit = (eye[1] > 0) & (rd[..., 1] < 0) & (np.maximum(np.abs(p[..., 0]), np.abs(p[..., 2])) <= extent)
    return np.stack([p[..., 0], -p[..., 2]], -1) / tile, hit


def bilinear_repeat(image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """GL_LINEAR + GL_REPEAT of image [N, M, C] (row 0 at v ~ 0) at uv [..., 2], float64."""
    h, w = image.shape[:2]

    def axis(t, n):
        p = t * n - 0.5
        i0 = np.floor(p)
        return np.mod(i0, n).astype(np.int64), np.mod(i0 + 1, n).astype(np.int64), (p - i0)[..., None]

    x0, x1, fx = axis(uv[..., 0], w)
    y0, y1, fy = axis(uv[..., 1], h)
    img = image.astype(np.float64)
    top = img[y0, x0] * (1 - fx) + img[y0, x1] * fx
    bot = img[y1, x0] * (1 - fx) + img[y1, x1] * fx
    return top * (1 - fy) + bot * fy


def ground_truth(image_tex: np.ndarray, camera, width: int, height: int, tile: float, extent: float,
                 ss: int = 8):
    """(encoded [H, W, C] mean of ss x ss bilinear base-level samples per pixel, mask [H, W] of
    pixels whose every sub-sample hits the plane and whose 8 neighbours' centres hit it too:
    derivatives across the plane's edge or the horizon are not the footprint)."""
    acc = np.zeros((height, width, image_tex.shape[2]))
    mask = np.ones((height, width), bool)
    grid = [((i + 0.5) / ss, (j + 0.5) / ss) for j in range(ss) for i in range(ss)]
    for off in grid:
        eye, rd = camera_rays(camera, width, height, [off])
        uv, hit = plane_uv(eye, rd[0], tile, extent)
        acc += bilinear_repeat(image_tex, uv)
        mask &= hit
    eye, rd = camera_rays(camera, width, height)
    centre = np.pad(plane_uv(eye, rd[0], tile, extent)[1], 1)
    for dy in (0, 1, 2):
        for dx in (0, 1, 2):
            mask &= centre[dy:dy + height, dx:dx + width]
    return acc / len(grid), mask


# ---------------------------------------------------------------------------------------------
# metrics

def psnr8(a: np.ndarray, b: np.ndarray, mask: np.ndarray) -> float:
    """PSNR of two sRGB-encoded [0, 1] images quantised to 8 bits, over `mask`."""
    return psnr(np.rint(np.clip(a, 0, 1) * 255.0), np.rint(np.clip(b, 0, 1) * 255.0), peak=255.0, mask=mask)


def encoded(linear_rgba: np.ndarray) -> np.ndarray:
    return srgb_oetf(linear_rgba[..., :3])


def di_reference(bundle, inputs: np.ndarray) -> np.ndarray:
    """The bundle in torch on the DI inputs the shader saw ([H, W, 4]: fract uv, log2 footprint,
    hit) -> linear [H, W, out]."""
    import torch

    from inshade.models import GraphModule

    g = GraphModule.from_bundle(bundle)
    x = torch.from_numpy(np.ascontiguousarray(inputs[..., :3].reshape(-1, 3), np.float32))
    with torch.no_grad():
        y = g(x).numpy()
    return y.reshape(*inputs.shape[:2], -1)


# ---------------------------------------------------------------------------------------------
# run

def _asset(args):
    """(bundle, image [N, N, k] sRGB-encoded row 0 = top, scene, origin)."""
    from inshade.bundle import load
    from inshade.techniques.di_footprint import train as fp
    from inshade.models import footprint_sampler as sampler
    from inshade.scene.description import load_scene

    path = Path(args.asset) if args.asset else None
    if not args.quick and path is not None and args.asset != DEFAULT_ASSET and not (path / "bundle.json").is_file():
        raise sampler.FootprintError(f"{path}: no di_footprint asset here (bundle.json); train one with "
                                f"`inshade train di_footprint --out {path}` or omit --asset")
    if not args.quick and path is not None and (path / "bundle.json").is_file():
        from PIL import Image

        bundle = load(path)
        image = np.asarray(Image.open(path / "texture.png").convert("RGB"), np.float32) / 255.0
        if bundle.meta["metrics"].get("channels") == 1:
            image = image[..., :1]
        return bundle, image, load_scene(path), f"asset `{portable_path(path)}`"
    d = fp.Settings()       # the trainer's quick preset
    size, steps = (32, 60) if args.quick else (d.size, args.steps or d.steps)
    image, _, source = fp.load_texture(d.image, size)
    result = fp.train_sampler(image, 1.5 if args.quick else d.ratio, n_cascaded=4 if args.quick else d.n_cascaded,
                              steps=steps)
    out = Path(args.out) / "di_footprint"
    fp.write_asset(result, out, preview_size=(64, 32))
    return result.bundle, image, load_scene(out), f"trained here ({source}, {steps} steps)"


def run(args) -> int:
    import torch

    from inshade.models import footprint_sampler as sampler
    from inshade.runtime.context import gl_info, shared_context

    if args.width < 1 or args.height < 1 or args.ss < 1:
        raise BenchError("--width, --height and --ss must be >= 1")
    ctx = shared_context()
    gl = gl_info(ctx)
    print(f"GL_RENDERER: {gl['renderer']}", file=sys.stderr)
    bundle, image, scene, origin = _asset(args)
    tex = np.ascontiguousarray(image[::-1])
    camera = scene.make_camera()
    tile = args.tile if args.tile is not None else scene.settings["tile"].default
    extent = args.extent if args.extent is not None else scene.settings["extent"].default
    for name, value in (("tile", tile), ("extent", extent)):   # the renders set them as scene settings
        try:
            scene.settings[name].check(value, "--" + name)
        except ValueError as exc:
            raise BenchError(str(exc)) from None
    w, h = args.width, args.height

    t0 = time.perf_counter()
    truth, mask = ground_truth(tex, camera, w, h, tile, extent, args.ss)
    truth_seconds = time.perf_counter() - t0

    renders, seconds = {}, {}
    inputs = None
    for lut_filter, modes in (("exact", ("di", *GL_MODES)), ("fast", ("di",))):
        r = PlaneRenderer(ctx, bundle, tex, lut_filter)
        try:
            for mode in modes:
                key = mode if lut_filter == "exact" or mode != "di" else "di_fast"
                t = time.perf_counter()
                colour, ins = r.render(mode, camera, w, h, tile, extent)
                seconds[key] = time.perf_counter() - t
                renders[key] = colour
                if key == "di":
                    inputs = ins
        finally:
            r.release()

    ref = di_reference(bundle, inputs)
    hit = inputs[..., 3] > 0.5
    parity = float(np.max(np.abs(renders["di"][..., :ref.shape[-1]][hit] - ref[hit]))) if hit.any() else 0.0
    # the emulated sampler (torch) at the shader's own (uv, footprint): how close GL's trilinear is to it
    chain = sampler.mip_chain(torch.from_numpy(tex.astype(np.float32)))
    x = torch.from_numpy(np.ascontiguousarray(inputs[..., :3].reshape(-1, 3), np.float32))
    emulated = sampler.emulated_trilinear(chain, x[:, :2], x[:, 2]).numpy().reshape(h, w, -1)

    k = image.shape[2]
    m = bundle.meta["metrics"]
    size = image.shape[0]
    bytes_di = int(m["bytes"])
    memory = {"di": bytes_di, "di_fast": bytes_di, "trilinear": sampler.texture_bytes(size, k, True),
              "anisotropic": sampler.texture_bytes(size, k, True), "bilinear": sampler.texture_bytes(size, k, False),
              "explicit_lod": sampler.texture_bytes(size, k, True)}
    labels = {"di": "DI footprint sampler (exact LUT path)", "di_fast": "DI footprint sampler (hardware filtering)",
              "trilinear": "GL trilinear (RGB8 + mips)",
              "anisotropic": f"GL anisotropic {min(MAX_ANISOTROPY, ctx.max_anisotropy):g}x (RGB8 + mips)",
              "bilinear": "no mips (bilinear base level)", "explicit_lod": "GL trilinear at the shader's LOD"}
    rows = []
    for key in ("di", "di_fast", "trilinear", "anisotropic", "bilinear", "explicit_lod"):
        enc = encoded(renders[key])
        if k == 1:
            enc = enc[..., :1]
        rows.append({"mode": key, "label": labels[key], "psnr_vs_truth": round(psnr8(enc, truth, mask), 3),
                     "bytes": memory[key], "draw_seconds": round(seconds[key], 4)})
    rows.append({"mode": "emulated_trilinear", "label": "emulated trilinear (torch, the DI training target)",
                 "psnr_vs_truth": round(psnr8(emulated, truth, mask), 3),
                 "bytes": sampler.texture_bytes(size, k, True), "draw_seconds": None})
    result = {
        "benchmark": "footprint", "origin": origin,
        "machine": machine(gl, max_anisotropy=float(ctx.max_anisotropy)),
        "view": {"width": w, "height": h, "camera": camera.to_dict(), "tile": tile, "extent": extent, "ss": args.ss,
                 "pixels_scored": int(mask.sum()), "ground_truth_seconds": round(truth_seconds, 2)},
        "texture": {"size": size, "channels": k,
                    "source": portable_command(bundle.meta["provenance"].get("image", ""))},
        "di": {key: m.get(key) for key in ("n_primary", "n_footprint", "n_cascaded", "n_lod", "rho", "bytes",
                                           "ratio_vs_base", "ratio_vs_mip_chain", "train_seconds", "steps",
                                           "psnr_heldout", "psnr_per_lod")},
        "parity_exact_max_abs_diff": parity,
        "di_vs_emulated_on_view_psnr": round(psnr8(encoded(renders["di"])[..., :k], emulated, mask & hit), 3),
        "history": m.get("history", []),
        "rows": rows,
    }
    out = Path(args.out)
    write_report(out, "di_footprint", result, markdown, plot)
    views(renders, truth * mask[..., None], k, out / "di_footprint_views.png")
    print(f"wrote {out / 'di_footprint.json'}, di_footprint.md, di_footprint.png, di_footprint_views.png",
          file=sys.stderr)
    return 0


def views(renders: dict, truth: np.ndarray, k: int, path: Path) -> None:
    """Ground truth (black where not scored) and every mode stacked vertically (linear, written
    sRGB), in order: truth, di, di_fast, trilinear, anisotropic, bilinear, explicit_lod."""
    from inshade.scene.image_io import write_png

    t = srgb_eotf(truth if k == 3 else np.repeat(truth, 3, -1))
    panels = [t] + [renders[key][..., :3] for key in ("di", "di_fast", "trilinear", "anisotropic", "bilinear",
                                                         "explicit_lod")]
    sep = np.ones((2, t.shape[1], 3))
    stack = []
    for p in panels:
        stack += [p, sep]
    with atomic_path(path) as tmp:
        write_png(tmp, np.concatenate(stack[:-1], 0))


def markdown(result: dict) -> str:
    m, v, d = result["machine"], result["view"], result["di"]
    lines = ["# DI footprint-aware sampler (no mip chain) vs GL sampling", "",
             machine_markdown(m),
             f"- view: {v['width']}x{v['height']}, grazing ground plane (camera {json.dumps(v['camera'])}), "
             f"tile {v['tile']:g}, plane half-size {v['extent']:g}; ground truth {v['ss']}x{v['ss']} bilinear sub-samples per pixel "
             f"({v['pixels_scored']} pixels scored); PSNR in sRGB 8-bit",
             f"- texture {result['texture']['size']}^2 x {result['texture']['channels']} "
             f"({result['texture']['source']}); DI: N_p0 {d['n_primary']}, N_p1 {d['n_footprint']}, "
             f"N_c {d['n_cascaded']}, N_lod {d['n_lod']}, {d['bytes']} bytes "
             f"({d['ratio_vs_base']}x vs RGB8, {d['ratio_vs_mip_chain']}x vs RGB8 + mips), "
             f"{d['steps']} steps in {d['train_seconds']} s; {result['origin']}",
             f"- DI vs emulated trilinear on held-out (uv, footprint): {d['psnr_heldout']} dB; per LOD: "
             + ", ".join(f"{k_}: {v_}" for k_, v_ in (d["psnr_per_lod"] or {}).items()),
             f"- DI vs emulated trilinear on this view (same uv and footprint per pixel): "
             f"{result['di_vs_emulated_on_view_psnr']:.2f} dB",
             f"- parity, exact LUT path vs torch on this view's inputs: max |diff| "
             f"{result['parity_exact_max_abs_diff']:.2g}", "",
             "| mode | PSNR vs truth dB | bytes | draw s |", "|---|---:|---:|---:|"]
    for r in result["rows"]:
        ds = "—" if r["draw_seconds"] is None else f"{r['draw_seconds']:.3f}"
        lines.append(f"| {r['label']} | {r['psnr_vs_truth']:.2f} | {r['bytes']} | {ds} |")
    lines += ["", "draw s: one draw incl. first-use shader compilation on this driver (not a speed benchmark)."]
    return "\n".join(lines) + "\n"


def plot(result: dict, path: Path) -> None:
    plt = matplotlib_pyplot()

    fig, (a, b, c) = plt.subplots(1, 3, figsize=(14, 4))
    rows = result["rows"]
    a.barh([r["mode"] for r in rows], [r["psnr_vs_truth"] for r in rows], color="tab:blue")
    for i, r in enumerate(rows):
        a.text(r["psnr_vs_truth"], i, f" {r['psnr_vs_truth']:.2f}", va="center", fontsize=8)
    a.set_xlabel("PSNR vs supersampled truth (sRGB 8-bit), dB")
    a.invert_yaxis()
    per = result["di"]["psnr_per_lod"] or {}
    b.plot([int(k) for k in per], list(per.values()), "o-")
    label_axes(b, "GL LOD (mip level)", "DI vs emulated trilinear, dB")
    hist = result.get("history") or []
    c.plot([r["seconds"] for r in hist], [r["psnr"] for r in hist], "o-", ms=3)
    label_axes(c, "training seconds", "held-out PSNR vs emulated trilinear (float), dB")
    save_figure(fig, path, "DI footprint sampler", result)


# ---------------------------------------------------------------------------------------------
# `inshade bench suite`: this bench's command line per preset, and its headline rows against the paper

CLAIMS = {"trilinear": Claim("Differentiable Indirection (Datta et al. 2023), Fig. 12",
                             "DI footprint sampler PSNR minus GL trilinear's (RGB8 + mips), vs supersampled truth (dB)",
                             "quality 'much superior to 1-spp ASTC' at 12x (no number in the text)")}


def headlines(r: dict) -> list[dict]:
    by = {row["mode"]: row for row in r["rows"]}
    di = by["di"]
    gl = next(row for row in r["rows"] if row["label"].startswith("GL trilinear (RGB8"))
    gap = di["psnr_vs_truth"] - gl["psnr_vs_truth"]
    return [claim_row(CLAIMS, "di_footprint", "trilinear", f"{gap:+.2f} dB: DI {di['psnr_vs_truth']:.2f} dB in "
                      f"{di['bytes']} B, trilinear {gl['psnr_vs_truth']:.2f} dB in {gl['bytes']} B", gap)]


BENCH = Bench("di_footprint", __doc__, Settings, run, errors=_errors, quick={"width": 96, "height": 48, "ss": 4},
              sizes={"cpu": sized(30, ss=8), "device": sized(45)}, claims=CLAIMS, headlines=headlines)
add_arguments, main, SUITE = BENCH.add_arguments, BENCH.main, BENCH.suite
