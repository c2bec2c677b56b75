"""The material balls drawn and measured (the paper's Fig. 6 / Fig. 11 protocol): torch renders of
the ball grid (techniques/di_brdf/material_balls.py) with the analytic and the learned BRDF -- GGX
through a cascade (`ggx_shade`), Disney through the exported graph (`graph_shade`) -- their ball
PSNRs in the display domain (`ggx_metrics`, `sweep_psnr`), and the same PSNR from the asset's own
shader through the GL driver (`glsl_psnr`).
"""
from __future__ import annotations

import numpy as np
import torch

from inshade.models import brdf
from inshade.models import indirection as di
from inshade.models.disney_glue import disney_glue
from inshade.models.graph import GraphModule
from inshade.techniques.di_brdf import VIEWS
from inshade.techniques.di_brdf import material_balls as mb

from .data import GGX_ALPHA_RANGE, GGX_KD, GGX_KS, SWEEP_COLUMNS, ggx_eval_set
from .model import DECODERS, DISNEY_OUTPUTS, analytic_d, learned_d


# GGX
def ggx_shade(d_fn):
    """Fig. 6 GGX ball shading with D given by `d_fn(alpha_h, nh)` (`analytic_d` or `learned_d`)."""
    def shade(sel, l, v, k):
        lo, hi = GGX_ALPHA_RANGE
        cols = shade.cols
        a = lo + (hi - lo) * (sel["col"].float() / float(max(cols - 1, 1)))
        h = brdf.half_vector(l, v)
        d = d_fn(a, h[..., 2])
        f = l[..., 2] * (GGX_KD * 0.5 * brdf.INV_PI + GGX_KS * d)
        f = torch.where((l[..., 2] > 0.0) & (v[..., 2] > 0.0), f, torch.zeros_like(f))
        return f[..., None].expand(-1, 3)
    return shade


def ggx_render(d_fn, cols: int = SWEEP_COLUMNS, size: int = 64, lights: int = 1) -> np.ndarray:
    shade = ggx_shade(d_fn)
    shade.cols = cols
    return mb.render(size * cols, size, cols, 1, shade, lights)


def ggx_metrics(g: GraphModule, cols: int = SWEEP_COLUMNS, size: int = 64) -> dict:
    """PSNR of the 8-bit GGX cascade: Fig. 6 ball row (display domain, per ball and mean) and the
    function itself on the sampling distribution (x / (1 + x) tone-mapped D, and raw D with peak max D)."""
    q = di.quantised_copy(g, 8)
    ref = ggx_render(analytic_d, cols, size)
    got = ggx_render(learned_d(q), cols, size)
    inside, ids = mb.ball_masks(size * cols, size, cols, 1)
    per_ball = [mb.ball_psnr(got, ref, inside & (ids == c)) for c in range(cols)]
    x, y = ggx_eval_set()
    with torch.no_grad():
        p = q(x)
    tm = lambda t: t / (1.0 + t)  # noqa: E731
    return {"psnr_balls_mean": float(np.mean(per_ball)), "psnr_balls_min": float(np.min(per_ball)),
            "psnr_balls": [round(v, 3) for v in per_ball],
            "psnr_balls_all_pixels": mb.ball_psnr(got, ref, inside),
            "psnr_function_tonemapped": di.psnr(tm(p), tm(y)),
            "psnr_function_raw_peak_max": di.psnr(p, y, float(y.max()))}


# Disney
def graph_shade(g: GraphModule):
    """Disney ball shading through the exported graph (what the GLSL evaluates): learned or analytic."""
    def lanes(sel):
        with torch.no_grad():
            y = g(sel["grid"])
        out, off = {}, 0
        for name, w in DISNEY_OUTPUTS:
            out[name] = y[..., off:off + w]
            off += w
        return out

    def shade(sel, l, v, k, learned):
        y = lanes(sel)
        if learned:
            dec = {n: y[n] for n in DECODERS}
            extra = {"sheen_tint": y["lat_a"][..., 2], "k": torch.stack(
                [y["lat_b"][..., 2], y["lat_b"][..., 3], y["lat_a"][..., 3]], -1)}
            albedo = torch.stack([y["lat_c"][..., 2], y["lat_c"][..., 3], y["lat_g"][..., 1]], -1)
            return disney_glue(dec, extra, albedo, l, v)
        par = torch.cat([y["par0"], y["par1"], y["par2"], y["par3"]], -1)
        return brdf.disney(l, v, par[..., :3], par[..., 3:13])
    return shade


def disney_render(g: GraphModule, view: str, cols: int, rows: int, size: int, lights: int = 1) -> np.ndarray:
    shade = graph_shade(g)
    halves = 2 if view == "split" else 1

    def fn(sel, l, v, k):
        if view == "split":
            learned = sel["side"] == 1
            a, b = shade(sel, l, v, k, False), shade(sel, l, v, k, True)
            return torch.where(learned[..., None], b, a)
        if view == "diffuse":
            with torch.no_grad():   # the baseline: albedo n.l / pi
                par = g(sel["grid"])
            off = sum(w for n, w in DISNEY_OUTPUTS[:DISNEY_OUTPUTS.index(("par0", 4))])
            return par[..., off:off + 3] * (l[..., 2:3].clamp(min=0.0) * brdf.INV_PI)
        return shade(sel, l, v, k, view == "learned")
    return mb.render(size * cols * halves, size * rows, cols, rows, fn, lights, halves)


def sweep_psnr(g: GraphModule, cols: int, rows: int, size: int = 32, lights: int = 2) -> dict:
    """Per artist parameter (row): min and mean ball PSNR (display domain) learned vs analytic."""
    ref = disney_render(g, "analytic", cols, rows, size, lights)
    got = disney_render(g, "learned", cols, rows, size, lights)
    inside, ids = mb.ball_masks(size * cols, size * rows, cols, rows)
    out = {}
    for r in range(rows):
        vals = [mb.ball_psnr(got, ref, inside & (ids == r * cols + c)) for c in range(cols)]
        out[brdf.PARAMS[r]] = {"min": round(min(vals), 3), "mean": round(float(np.mean(vals)), 3),
                               "per_ball": [round(v, 2) for v in vals]}
    return out


# the asset's shader
def glsl_psnr(folder, model: str, lut_filter: str, ball_px: int) -> dict:
    """Quality from the shader's own output: the asset's material-ball pass rendered through the GL
    driver with the analytic and the learned BRDF (2 lights), ball PSNR in the display domain;
    Disney: min per row (artist parameter), GGX: per ball. Also returns GL_RENDERER."""
    from inshade.scene.camera import camera_from_dict
    from inshade.runtime.render import read_rgba
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import load_scene

    scene = load_scene(folder)
    cols = scene.settings["cols"].default
    rows = scene.settings["rows"].default
    w, h = cols * ball_px, rows * ball_px
    cam = camera_from_dict({"type": "plane2d", "aspect": w / h})
    imgs = {}
    for view in ("analytic", "learned"):
        r = SceneRenderer(scene, settings={"view": VIEWS[view], "lut_filter": lut_filter, "lights": 2})
        try:
            imgs[view] = read_rgba(r.render_network(cam, w, h))[..., :3]
            renderer = r.gl["renderer"]
        finally:
            r.release()
    inside, ids = mb.ball_masks(w, h, cols, rows)
    per = [[mb.ball_psnr(imgs["learned"], imgs["analytic"], inside & (ids == rr * cols + c)) for c in range(cols)]
           for rr in range(rows)]
    out = {"gl_renderer": renderer, "lut_filter": lut_filter}
    if model == "disney":
        out["rows_min"] = {brdf.PARAMS[rr]: round(min(per[rr]), 3) for rr in range(rows)}
        out["min"] = min(out["rows_min"].values())
    else:
        out["per_ball"] = [round(v, 3) for v in per[0]]
        out["mean"], out["min"] = float(np.mean(per[0])), float(np.min(per[0]))
        out["all_pixels"] = mb.ball_psnr(imgs["learned"], imgs["analytic"], inside)
    return out
