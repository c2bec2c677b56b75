"""End-to-end optimised shading pipeline with Differentiable Indirection (Datta et al. 2023 §4.3.3,
supp. 1.5): the footprint-aware DI texture sampler (techniques/di_footprint) trained to be aware of
the learned DI Disney BRDF (techniques/di_brdf, the shipped trained/di_brdf_disney), on the PBR
bricks set (techniques/di_pbr_set: albedo, normal, roughness, AO; 8 lanes) on a lit ground plane
seen at grazing angles.

The pipeline, per pixel (passes/shading_plane.frag; torch twin `shade_di` / `reference`):

    (fract uv, log2 footprint) -> DI footprint sampler (2D primary + 1D footprint primary -> 4D
        cascaded, 8 lanes, 8-bit arrays, no mip chain) -> lanes
    lanes -> unpack (lib/pbr_set: sRGB albedo, tangent-space normal, roughness, AO)
    roughness -> frozen DI Disney "brdf" bundle: the offline encoders' rows at the set's constant
        artist parameters (anisotropic = subsurface = 0, one 1D 64-cell lookup, 4 channels) and the
        five runtime decoders of trained/di_brdf_disney (16x16 ggx / smith / diff / coef, 16 gloss)
    -> lib/di_brdf glue, one point light (I / d^2) + an ambient term albedo * AO * ambient.

The set's other Disney parameters are constants: metallic 0, specular 0.5, specular_tint 0,
sheen 0, sheen_tint 0.5, clearcoat 0, clearcoat_gloss 1 (as techniques/di_pbr_set shades it).

Training (`train_sweep`): one (uv, footprint, light, view) data set drawn like the plane's pixels
(`plane_samples`: random grazing fly cameras, pixels of a 512x256 view, uv derivatives by
differences between neighbouring pixels on 2x2 quads, as llvmpipe forms dFdx/dFdy; tested against
the pass's G-buffer), then for each lambda, the same sampler initialisation, the same batches, the
same steps and seed:

    loss = (1 - lambda) |sampler - proxy| + lambda |display(shade_di(sampler)) - display(reference)|

- proxy: di_footprint's `emulated_trilinear` of the set (GL_LINEAR_MIPMAP_LINEAR, 8-bit box mips);
- reference ("appearance filtering", `reference`): 16 samples on a 4x4 grid over the pixel footprint
  uv + a duv/dx + b duv/dy (a, b in {-3/8, -1/8, 1/8, 3/8}: the pixel's parallelogram, first order),
  each prefiltered by the proxy trilinear sampler at a quarter of the footprint (log2 footprint - 2)
  and shaded with the ANALYTIC Disney BRDF (models/brdf.py), averaged. The paper assumes an
  axis-aligned footprint; the parallelogram is the pixel's own, so the training reference and
  the GLSL reference view (SHADING_VIEW reference) are the same formula;
- display(x) = sRGB(clamp(exposure x, 0, 1)), the domain the PSNR / FLIP are measured in;
- the decoder is frozen (requires_grad False; gradients flow through its lookups to the lanes);
- metallic-path clipping (`metal_clip`): the shaded term is split into its GGX lobe D_m G_m (the
  unbounded "metallic" component; its value is the glue's with the ggx decoder output as given
  minus the glue's with D_m -> 0) and the rest, and the gradient reaching the sampler's lanes
  through that lobe is clipped per sample to an L2 norm <= metal_clip / batch (a tensor hook);
- a sample whose shaded-term gradient is not finite (torch.where's backward through the glue's
  masked below-horizon branch) has it dropped, and is counted (metrics: nonfinite_gradient_samples);
- Adam, cosine schedule (lr to 5%), lambda = 0 is the independently trained sampler (baseline).

Command: ``inshade train di_shading --force -o trained/di_shading_bricks [--preset quick|ship] [--device
auto|cpu|cuda[:N]]``. ``--preset ship`` is exactly what built trained/di_shading_bricks; ``quick``
(the default) is a small run. ``--device`` (inshade/devices.py; auto: CUDA when torch sees one)
places the training: the mip chain, the data set's proxies and references, the samplers, the frozen
decoder, every step and the held-out evaluation run there. Random numbers are drawn on seeded CPU
generators (numpy for the views and pixels, torch for the batches and the initialisation), so every
device trains on the same data and batches; the samplers and the decoder come back to the CPU for
export. OUT/metrics.json records the preset, the resolved settings, the device and the lambda sweep.
"""
from __future__ import annotations

import argparse
import datetime
import json
import shlex
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from inshade import asset_folder, command
from inshade.devices import DeviceError, add_device_argument, resolve_device
from inshade.files import atomic_write
from inshade.models import brdf
from inshade.models import indirection as di
from inshade.models.graph import GraphModule
from inshade.models.lookup_array import LookupArray
from inshade.models.mlp import Dense
from inshade.models.disney_glue import disney_glue
from inshade.models.display import srgb_display
from inshade.models import footprint_sampler as fp
from inshade.models import pbr_lanes

KIND = "di_shading"
DECODER_KIND = "di_shading_brdf"
PROGRAM = "passes/shading_plane.frag"
CHANNELS = 8
# SHADING_VIEW of passes/shading_plane.frag (mirrored there as constants)
VIEWS = {"end_to_end": 0, "independent": 1, "reference": 2, "split": 3, "trilinear": 4, "analytic": 5}
LAMBDAS = (0.0, 0.1, 0.25, 0.5)
# the scene: one point light ahead of the camera, low (its glossy reflection lies at grazing
# angles), plus a uniform ambient term albedo * AO * AMBIENT
LIGHT_POSITION = (0.0, 0.6, -5.0)
LIGHT_INTENSITY = 20.0
AMBIENT = 0.08
MIN_NV = 0.05   # lib/di_shading DI_SHADING_MIN_NV: the least n.v a set normal shades with
EXPOSURE = 1.0
# the set's constant Disney parameters (brdf.PARAMS order; roughness comes from the set)
CONSTANTS = {"metallic": 0.0, "anisotropic": 0.0, "subsurface": 0.0, "specular": 0.5, "specular_tint": 0.0,
             "sheen": 0.0, "sheen_tint": 0.5, "clearcoat": 0.0, "clearcoat_gloss": 1.0}
# the glue's per-texel scalars at those constants (di_brdf DisneyDI.extras): R0 specular specular_tint,
# R0 specular (1 - specular_tint), clearcoat / 4
K_EXTRA = (0.0, float(np.float32(brdf.R0 * 0.5)), 0.0)
SUB = (-0.375, -0.125, 0.125, 0.375)     # 4x4 footprint sample grid (pixel units)
VIEW_SIZE = (512, 256)
DEFAULT_BRDF = "trained/di_brdf_disney"
REPO = Path(__file__).resolve().parents[2]
DEFAULTS = dict(size=128, ratio=6.0, n_cascaded=4, steps=1500, lr=1e-2, batch=4096, samples=1 << 17,
                views=12, metal_clip=1.0, seed=0, lambdas=list(LAMBDAS))
PRESETS = {"quick": dict(size=64, steps=300, samples=1 << 15, views=4),
           "ship": dict(size=128, steps=1500, samples=1 << 17, views=12)}
SETTINGS = ("size", "ratio", "n_cascaded", "steps", "lr", "batch", "samples", "views", "metal_clip", "seed",
            "lambdas")


class ShadingError(ValueError):
    """A setting or input the end-to-end trainer cannot use; the message names it."""


def preset_settings(preset: str, asset: str | None = None) -> dict:
    """The settings ``--preset PRESET`` resolves to with no other option (one asset)."""
    return {k: PRESETS[preset].get(k, DEFAULTS[k]) for k in SETTINGS}


def lambda_folder(lam: float) -> str:
    """Sub-folder of the asset holding the sampler trained with weight `lam` (lambda_000 .. lambda_050)."""
    return f"lambda_{int(round(lam * 100)):03d}"


# ---------------------------------------------------------------------------------------------
# the frozen DI Disney decoder as a bundle graph

def _load_cells(path: Path) -> dict:
    from safetensors.numpy import load_file

    return {k: torch.from_numpy(v.astype(np.float32)) for k, v in load_file(str(path)).items()}


def decoder_graph(folder=DEFAULT_BRDF) -> GraphModule:
    """Input ``roughness`` (1) -> the five decoders of a di_brdf_disney asset (outputs ggx 3, smith 1,
    diff 4, coef 4, gloss 2 = 14 lanes), frozen, 32-bit. Latents: ``enc`` is the 1D row of the
    offline encoders E_m (roughness, anisotropic = 0) and E_d (roughness, subsurface = 0): the
    cells of a 2D array along one edge, so the 1D lookup equals the 2D one there; E_c at
    (metallic 0, sheen 0) and E_g at clearcoat_gloss 1 are constants (bias-only dense nodes)."""
    from inshade import bundle as bundle_io

    folder = Path(folder)
    if not folder.is_absolute() and not folder.exists() and (REPO / folder).exists():
        folder = REPO / folder          # the default, from any working directory
    if not (folder / "encoders.safetensors").is_file():
        raise ShadingError(f"{folder}: brdf: not a di_brdf_disney asset (no encoders.safetensors); "
                           "build one with `inshade train di_brdf disney -o DIR`")
    src = GraphModule.from_bundle(bundle_io.load(folder))
    enc = _load_cells(folder / "encoders.safetensors")
    row = torch.cat([enc["E_m.cells"][0], enc["E_d.cells"][0]], -1)            # [64, 4]
    z_c, z_g = enc["E_c.cells"][0, 0], enc["E_g.cells"][-1]
    g = GraphModule([("roughness", 1, "roughness")])
    g.add("enc", LookupArray([row.shape[0]], 4, 32, init=row.clone()), "roughness")
    for name, lanes in (("z_m", (0, 1)), ("z_d", (2, 3))):
        pick = Dense(4, 2, bias=False)
        with torch.no_grad():
            pick.linear.weight.zero_()
            for i, lane in enumerate(lanes):
                pick.linear.weight[i, lane] = 1.0
        g.add(name, pick, "enc")
    for name, value in (("z_c", z_c), ("z_g", z_g)):
        const = Dense(1, len(value))
        with torch.no_grad():
            const.linear.weight.zero_()
            const.linear.bias.copy_(value)
        g.add(name, const, "roughness")
    source = {"ggx": "z_m", "smith": "z_m", "diff": "z_d", "coef": "z_c", "gloss": "z_g"}
    for name, z in source.items():
        dec = src.nodes[name]
        g.add(name, LookupArray(dec.resolution, dec.channels, 32, init=dec.table().detach().clone()), z)
    for name in source:
        g.output(name, name, name)
    for p in g.parameters():
        p.requires_grad_(False)
    return g


def split_decoders(y: torch.Tensor) -> dict:
    return {"ggx": y[..., 0:3], "smith": y[..., 3:4], "diff": y[..., 4:8], "coef": y[..., 8:12],
            "gloss": y[..., 12:14]}


# ---------------------------------------------------------------------------------------------
# shading (torch twins of lib/di_shading.glsl)

def _dot(a, b):
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def unpack(lanes: torch.Tensor) -> dict:
    """lib/pbr_set pbr_set_unpack of 8 lanes [N, 8] (di_pbr_set's `unpack`)."""
    return pbr_lanes.unpack(lanes[:, :4], lanes[:, 4:])


def visible_normal(normal_ts: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """di_shading_visible_normal: a normal with n.v < MIN_NV bent toward the eye v (n + v (MIN_NV - n.v),
    normalised), so a bumpy sample seen at grazing angles does not shade as its unlit back."""
    nv = _dot(normal_ts, v)
    m = normal_ts + v * (np.float32(MIN_NV) - nv)[:, None]
    bent = m * torch.rsqrt(_dot(m, m))[:, None]
    return torch.where((nv >= np.float32(MIN_NV))[:, None], normal_ts, bent)


def local_frame(normal_ts: torch.Tensor):
    """di_shading_frame: an orthonormal frame around the tangent-space normal, tangent from +u."""
    t = torch.zeros_like(normal_ts)
    t[:, 0] = 1.0
    t = t - normal_ts * normal_ts[:, 0:1]
    t = t * torch.rsqrt(torch.clamp(_dot(t, t), min=1e-30))[:, None]
    b = torch.cross(normal_ts, t, dim=-1)
    return lambda w: torch.stack([_dot(w, t), _dot(w, b), _dot(w, normal_ts)], -1)


@dataclass
class Geometry:
    """Per sample: l, v (unit, plane tangent space: x = +u, y = +v, z = the plane normal) and the
    light's irradiance scale I / d^2."""
    l: torch.Tensor
    v: torch.Tensor
    e: torch.Tensor

    def index(self, idx):
        return Geometry(self.l[idx], self.v[idx], self.e[idx])


def plane_geometry(p: torch.Tensor, eye, light=LIGHT_POSITION, intensity=LIGHT_INTENSITY) -> Geometry:
    """World hit points p [N, 3] on y = 0 -> Geometry (di_shading_geometry), on p's device."""
    eye = torch.as_tensor(eye, dtype=torch.float32, device=p.device)
    d = torch.tensor(light, dtype=torch.float32, device=p.device) - p
    d2 = _dot(d, d)
    lw = d * torch.rsqrt(d2)[:, None]
    vw = eye - p
    vw = vw * torch.rsqrt(_dot(vw, vw))[:, None]
    ts = lambda w: torch.stack([w[:, 0], -w[:, 2], w[:, 1]], -1)  # noqa: E731
    return Geometry(ts(lw), ts(vw), np.float32(intensity) / d2)


def _params(roughness: torch.Tensor) -> torch.Tensor:
    p = torch.zeros(len(roughness), len(brdf.PARAMS), device=roughness.device)
    for k, v in CONSTANTS.items():
        p[:, brdf.PARAMS.index(k)] = v
    p[:, brdf.PARAMS.index("roughness")] = roughness
    return p


def shade_analytic(lanes: torch.Tensor, geo: Geometry, ambient: float = AMBIENT) -> torch.Tensor:
    """di_shading_analytic: analytic Disney (models/brdf.py) of the unpacked lanes, linear [N, 3]."""
    s = unpack(lanes)
    local = local_frame(visible_normal(s["normal_ts"], geo.v))
    f = brdf.disney(local(geo.l), local(geo.v), s["albedo"], _params(s["roughness"]))
    return f * geo.e[:, None] + s["albedo"] * (np.float32(ambient) * s["ao"])[:, None]


def shade_di(lanes: torch.Tensor, geo: Geometry, decoder: GraphModule, ambient: float = AMBIENT,
             no_metal: bool = False) -> torch.Tensor:
    """di_shading_learned: the frozen DI Disney decoder + glue (di_brdf `disney_glue`), linear [N, 3].
    `no_metal`: the GGX lobe D_m G_m set to ~0 (ggx denominators 1e6), for the metallic-path split."""
    s = unpack(lanes)
    local = local_frame(visible_normal(s["normal_ts"], geo.v))
    dec = split_decoders(decoder(s["roughness"][:, None]))
    if no_metal:
        dec["ggx"] = torch.full_like(dec["ggx"], 1e6)
    n = len(lanes)
    extra = {"sheen_tint": torch.full((n,), float(CONSTANTS["sheen_tint"]), device=lanes.device),
             "k": torch.tensor(K_EXTRA, dtype=torch.float32, device=lanes.device).expand(n, 3)}
    f = disney_glue(dec, extra, s["albedo"], local(geo.l), local(geo.v))
    return f * geo.e[:, None] + s["albedo"] * (np.float32(ambient) * s["ao"])[:, None]


def _clip_rows(bound: float):
    def hook(g):
        g = torch.nan_to_num(g, nan=0.0, posinf=0.0, neginf=0.0)
        norm = torch.sqrt((g * g).sum(-1, keepdim=True))
        return g * torch.clamp(bound / torch.clamp(norm, min=1e-30), max=1.0)
    return hook


def shade_di_clipped(lanes, geo, decoder, bound: float | None):
    """`shade_di` whose gradient through the GGX lobe (the metallic path) is clipped per sample at
    the lanes to an L2 norm <= bound (None: unclipped). Value: rest + (full - rest) = `shade_di`."""
    if bound is None:
        return shade_di(lanes, geo, decoder)
    lm = lanes.clone()
    if lm.requires_grad:
        lm.register_hook(_clip_rows(bound))
    rest = shade_di(lanes, geo, decoder, no_metal=True)
    return rest + (shade_di(lm, geo, decoder) - shade_di(lm, geo, decoder, no_metal=True))


def display(x: torch.Tensor, exposure: float = EXPOSURE) -> torch.Tensor:
    """sRGB(clamp(exposure x, 0, 1)): the domain of the shaded loss, PSNR and FLIP."""
    return srgb_display(x * np.float32(exposure))


def reference(chain, uv, dx, dy, log2_fp, geo: Geometry) -> torch.Tensor:
    """Appearance filtering: 16 samples uv + a dx + b dy (a, b in SUB), each the proxy trilinear
    sampler at log2 footprint - 2, shaded with the analytic Disney BRDF; the mean, linear [N, 3]
    (on the device the inputs and `chain` live on)."""
    acc = torch.zeros(len(uv), 3, device=uv.device)
    for b in SUB:
        for a in SUB:
            lanes = fp.emulated_trilinear(chain, uv + np.float32(a) * dx + np.float32(b) * dy, log2_fp - 2.0)
            acc = acc + shade_analytic(lanes, geo)
    return acc * np.float32(1.0 / 16.0)


# ---------------------------------------------------------------------------------------------
# training data: the plane's pixels

def plane_camera(rng: np.random.Generator) -> dict:
    """A grazing fly camera over the plane, looking roughly towards the light (-z)."""
    return {"type": "fly", "position": [float(rng.uniform(-4, 4)), float(rng.uniform(0.12, 0.7)),
                                        float(rng.uniform(-1.0, 3.0))],
            "yaw": float(rng.uniform(-30, 30)), "pitch": float(rng.uniform(-22, -3)), "fov_y": 50.0,
            "near": 0.05, "far": 100.0}


def pixel_rays(camera: dict, width: int, height: int):
    """(eye [3], directions [H, W, 3]) as lib/camera camera_ray, image orientation (row 0 = top)."""
    from inshade.models.sdf import camera_rays
    from inshade.runtime.camera import camera_from_dict

    u = camera_from_dict(camera).uniforms(width, height)
    ro, rd = camera_rays(u, width, height)
    return torch.tensor(u["u_eye"], dtype=torch.float32), rd.reshape(height, width, 3)


def plane_pixels(camera: dict, width: int, height: int, tile: float = fp.TILE, extent: float = fp.EXTENT):
    """Per pixel of a view: uv (tiled), duv/dx, duv/dy (neighbour differences, as dFdx / dFdy),
    world hit point and hit mask; [H, W, ...]."""
    eye, rd = pixel_rays(camera, width, height)
    t = eye[1] / torch.clamp(-rd[..., 1], min=1e-6)
    p = eye + rd * t[..., None]
    hit = (eye[1] > 0) & (rd[..., 1] < 0) & (torch.maximum(p[..., 0].abs(), p[..., 2].abs()) <= extent)
    uv = torch.stack([p[..., 0], -p[..., 2]], -1) / tile
    # dFdx / dFdy as llvmpipe forms them on 2x2 quads: dx = uv(x0 + 1) - uv(x0) on the pixel's row,
    # x0 = x - x % 2; dy = uv(y0 + 1) - uv(y0) on its column, y0 = y - y % 2 (GL window y, up)
    x = torch.arange(width)
    x0 = torch.clamp(x - x % 2, max=width - 2)
    dx = uv[:, x0 + 1] - uv[:, x0]
    y = height - 1 - torch.arange(height)                   # GL y of each image row
    y0 = torch.clamp(y - y % 2, max=height - 2)
    dy = uv[height - 1 - (y0 + 1)] - uv[height - 1 - y0]
    return uv, dx, dy, p, hit, eye


@dataclass
class Samples:
    x: torch.Tensor          # [N, 3] (fract uv, log2 footprint): the sampler's input
    proxy: torch.Tensor      # [N, 8] emulated trilinear lanes
    ref: torch.Tensor        # [N, 3] appearance-filtered reference, linear
    geo: Geometry

    def index(self, idx):
        return Samples(self.x[idx], self.proxy[idx], self.ref[idx], self.geo.index(idx))


def log2_footprint(dx, dy):
    """lib/footprint footprint_log2: 0.5 log2(max(|dx|^2, |dy|^2))."""
    return 0.5 * torch.log2(torch.clamp(torch.maximum((dx * dx).sum(-1), (dy * dy).sum(-1)), min=1e-30))


def plane_samples(chain, n: int, views: int, seed: int, size=VIEW_SIZE) -> Samples:
    """n hit pixels drawn uniformly from `views` random grazing views (`plane_camera`) at `size`,
    with their proxy targets and appearance-filtered references (computed once): `plane_draw` on
    the CPU (a numpy generator: the same pixels on every device), then `plane_targets` on the
    device `chain` lives on."""
    return plane_targets(chain, plane_draw(n, views, seed, size))


def plane_draw(n: int, views: int, seed: int, size=VIEW_SIZE) -> dict:
    """The pixels of `plane_samples`, on the CPU: {uv (tiled), dx, dy, p, eye} [n, ...]."""
    rng = np.random.default_rng(seed)
    cols = {k: [] for k in ("uv", "dx", "dy", "p", "eye")}
    per = -(-n // views)
    for _ in range(views):
        uv, dx, dy, p, hit, eye = plane_pixels(plane_camera(rng), *size)
        # keep pixels whose footprint is finite (a neighbour off the plane gives a huge one)
        ok = hit & torch.isfinite(log2_footprint(dx, dy)) & (log2_footprint(dx, dy) < 2.0)
        idx = torch.nonzero(ok.reshape(-1))[:, 0]
        pick = idx[torch.from_numpy(rng.choice(len(idx), min(per, len(idx)), replace=False))]
        for k, v in (("uv", uv), ("dx", dx), ("dy", dy), ("p", p)):
            cols[k].append(v.reshape(-1, v.shape[-1])[pick])
        cols["eye"].append(eye.expand(len(pick), 3))
    return {k: torch.cat(v)[:n] for k, v in cols.items()}


def plane_targets(chain, pixels: dict) -> Samples:
    """`plane_draw`'s pixels -> Samples: footprints, geometry, references and proxies, computed on
    the device `chain` lives on (the pixels are moved there)."""
    c = {k: v.to(chain[0].device) for k, v in pixels.items()}
    lf = log2_footprint(c["dx"], c["dy"])
    geo = plane_geometry(c["p"], c["eye"])
    uv = c["uv"] - torch.floor(c["uv"])
    out_ref = []
    with torch.no_grad():
        for s in range(0, len(uv), 16384):
            sl = slice(s, s + 16384)
            out_ref.append(reference(chain, uv[sl], c["dx"][sl], c["dy"][sl], lf[sl], geo.index(sl)))
        proxy = fp.emulated_trilinear(chain, uv, lf)
    return Samples(torch.cat([uv, lf[:, None]], -1), proxy, torch.cat(out_ref), geo)


# ---------------------------------------------------------------------------------------------
# training

@dataclass
class Run:
    lam: float
    graph: GraphModule       # trained float sampler core (outputs 8 lanes)
    bundle: object           # exported 8-bit bundle
    history: di.History
    metrics: dict = field(default_factory=dict)


def _finite_rows(counter: list):
    """Gradient hook: zero the rows (samples) whose gradient is not finite, counting them. The glue's
    masked branches (below-horizon 1 / (n.l + n.v), a ~0 normal's 1 / |n|) can give 0 x inf = NaN
    through torch.where's backward even where the value is fine. The count accumulates as a tensor
    on the gradient's device (no host sync per step); `int(counter[0])` reads it."""
    def hook(g):
        bad = ~torch.isfinite(g).all(-1, keepdim=True)
        counter[0] = counter[0] + bad.sum()
        return torch.where(bad, torch.zeros_like(g), g)
    return hook


def objective(lam: float, decoder: GraphModule, metal_clip: float | None, batch_size: int,
              nonfinite: list | None = None):
    """The sampler's loss for weight `lam` (module docstring). `nonfinite`: a one-item list counting
    the samples whose shaded-term gradient was dropped as non-finite."""
    bound = None if metal_clip is None else metal_clip / batch_size
    counter = nonfinite if nonfinite is not None else [0]

    def fn(core, b: Samples):
        lanes = core(b.x)
        loss = torch.mean(torch.abs(lanes - b.proxy))
        if lam == 0.0:
            return loss
        shaded_lanes = lanes.clone()
        if shaded_lanes.requires_grad:
            shaded_lanes.register_hook(_finite_rows(counter))
        shaded = torch.nan_to_num(display(shade_di_clipped(shaded_lanes, b.geo, decoder, bound)))
        with torch.no_grad():
            ref = display(b.ref)
        return (1.0 - lam) * loss + lam * torch.mean(torch.abs(shaded - ref))
    return fn


def evaluate(core: GraphModule, s: Samples, decoder: GraphModule) -> dict:
    """PSNR of the sampler's lanes vs the proxy, and of its DI-shaded display values vs the reference."""
    with torch.no_grad():
        lanes = core(s.x)
        shaded = display(shade_di(lanes, s.geo, decoder))
        ref = display(s.ref)
        proxy_shaded = display(shade_di(s.proxy, s.geo, decoder))
    return {"psnr_lanes_vs_proxy": round(di.psnr(lanes, s.proxy), 4),
            "psnr_shaded_vs_reference": round(di.psnr(shaded, ref), 4),
            "psnr_proxy_shaded_vs_reference": round(di.psnr(proxy_shaded, ref), 4)}


def batches(data: Samples, batch: int, seed: int):
    """Endless batches of `data`: indices drawn on a seeded CPU generator (the same batches on every
    device), gathered on the device `data` lives on."""
    gen = torch.Generator().manual_seed(seed)
    while True:
        yield data.index(torch.randint(0, len(data.x), (batch,), generator=gen).to(data.x.device))


def material(size: int) -> np.ndarray:
    """The bricks set [N, N, 8] (sRGB albedo, normal, roughness, AO), row 0 = top."""
    if size < 32 or size & (size - 1):
        raise ShadingError(f"size: {size} must be a power of two >= 32 (a full mip chain; bricks courses)")
    return pbr_lanes.bricks(size)


def train_sweep(size=DEFAULTS["size"], ratio=DEFAULTS["ratio"], n_cascaded=DEFAULTS["n_cascaded"],
                steps=DEFAULTS["steps"], lr=DEFAULTS["lr"], batch=DEFAULTS["batch"], samples=DEFAULTS["samples"],
                views=DEFAULTS["views"], metal_clip=DEFAULTS["metal_clip"], seed=DEFAULTS["seed"],
                lambdas=LAMBDAS, brdf_folder=DEFAULT_BRDF, progress=None, name="di_shading", device=None):
    """Train one sampler per lambda (same init, data, batches, steps, seed) on `device` (default the
    CPU; module docstring). Returns (runs, decoder, image, data info), the runs' samplers and the
    decoder on the CPU."""
    device = torch.device("cpu") if device is None else torch.device(device)
    for lam in lambdas:
        if not (0.0 <= float(lam) < 1.0):
            raise ShadingError(f"lambdas: {lam!r}: each lambda must be in [0, 1) (lambda = 1 is unstable)")
    if 0.0 not in [float(x) for x in lambdas]:
        raise ShadingError("lambdas: must include 0 (the independently trained baseline)")
    if steps < 0 or batch < 1 or samples < 1 or views < 1:
        raise ShadingError("steps >= 0, batch >= 1, samples >= 1 and views >= 1 are required")
    image = material(size)
    chain = fp.mip_chain(fp.texture_tensor(image).to(device))
    decoder = decoder_graph(brdf_folder).to(device)
    sizing = fp.plan(size, CHANNELS, ratio, n_cascaded)
    t0 = time.perf_counter()
    data = plane_samples(chain, samples, views, seed)
    held = plane_samples(chain, min(16384, samples), max(2, views // 2), seed + 1000)
    data_seconds = time.perf_counter() - t0
    runs = []
    for lam in lambdas:
        lam = float(lam)
        torch.manual_seed(seed)
        core = fp.sampler_graph(size, sizing, image.reshape(-1, CHANNELS).mean(0)).to(device)  # CPU init
        ev = held.index(torch.arange(min(4096, len(held.x)), device=device))

        def metric(c, ev=ev, lam=lam):
            m = evaluate(c, ev, decoder)
            return 0.0, m["psnr_shaded_vs_reference"]

        t1 = time.perf_counter()
        nonfinite = [0]
        hist = di.train_cascade(core, batches(data, batch, seed), steps, lr=lr, schedule="cosine", seed=seed,
                                objective=objective(lam, decoder, metal_clip, batch, nonfinite), metric=metric,
                                progress=progress, desc=f"{name} lambda {lam:g}")
        seconds = time.perf_counter() - t1
        core = core.to("cpu")             # the result, on the CPU for export
        for p in core.parameters():
            p.requires_grad_(False)
        bundle = core.export(KIND, lambda_folder(lam), provenance={"lambda": lam})
        q = GraphModule.from_bundle(bundle).to(device)
        m = {"lambda": lam, "train_seconds": round(seconds, 2), **evaluate(q, held, decoder),
             "nonfinite_gradient_samples": int(nonfinite[0]),
             "history": [{"step": r["step"], "psnr_shaded": round(r["psnr"], 3)} for r in hist.records]}
        runs.append(Run(lam, core, bundle, hist, m))
    info = {"bytes": sizing.bytes, "n_primary": sizing.n_primary, "n_footprint": sizing.n_footprint,
            "n_cascaded": sizing.n_cascaded, "n_lod": sizing.n_lod,
            "ratio_vs_base": round(fp.texture_bytes(size, CHANNELS, False) / sizing.bytes, 4),
            "data_seconds": round(data_seconds, 2), "samples": len(data.x), "heldout": len(held.x)}
    return runs, decoder.to("cpu"), image, info


def best_run(runs):
    """The lambda > 0 run with the highest held-out shaded PSNR (8-bit sampler, DI decoder)."""
    cands = [r for r in runs if r.lam > 0] or runs
    return max(cands, key=lambda r: r.metrics["psnr_shaded_vs_reference"])


# ---------------------------------------------------------------------------------------------
# the asset

def scene_dict(name: str, title: str, e2e: str, size=VIEW_SIZE, view: str = "split") -> dict:
    return {
        "format": "inshade.scene", "version": 1, "name": name, "title": title,
        "program": PROGRAM, "size": list(size),
        "networks": [{"bundle": e2e, "prefix": "e2e"}, {"bundle": lambda_folder(0.0), "prefix": "ind"},
                     {"bundle": "brdf", "prefix": "brdf"}],
        "textures": [{"uniform": "u_set0", "image": "set0.png", "mipmaps": True, "repeat": True},
                     {"uniform": "u_set1", "image": "set1.png", "mipmaps": True, "repeat": True}],
        "camera": fp.CAMERA,
        "bookmarks": {"grazing": fp.CAMERA,
                      "steeper": {**fp.CAMERA, "position": [0.0, 0.6, 0.0], "pitch": -25.0},
                      "horizon": {**fp.CAMERA, "position": [0.0, 0.15, 0.0], "pitch": -3.0}},
        "lights": [{"type": "point", "position": list(LIGHT_POSITION), "intensity": LIGHT_INTENSITY}],
        "environment": None,
        "display": {"mode": "final", "modes": ["final", "network"], "split": 0.5},
        "settings": {
            "view": {"type": "choice", "default": VIEWS[view], "choices": sorted(VIEWS.values()),
                     "define": "SHADING_VIEW", "label": "view: " + ", ".join(f"{v} {k}" for k, v in VIEWS.items())},
            "exposure": {"type": "float", "default": EXPOSURE, "min": 0.0, "max": 8.0, "uniform": "u_exposure",
                         "label": "exposure"},
            "extent": {"type": "float", "default": fp.EXTENT, "min": 0.5, "max": 1000.0, "uniform": "u_extent",
                       "label": "plane half-size (world units)"},
            "tile": {"type": "float", "default": fp.TILE, "min": 0.05, "max": 20.0, "uniform": "u_tile",
                     "label": "tile size (world units)"},
            "light_x": {"type": "float", "default": LIGHT_POSITION[0], "min": -20.0, "max": 20.0,
                        "uniform": "u_light_x", "label": "light x"},
            "light_y": {"type": "float", "default": LIGHT_POSITION[1], "min": 0.01, "max": 20.0,
                        "uniform": "u_light_y", "label": "light height"},
            "light_z": {"type": "float", "default": LIGHT_POSITION[2], "min": -20.0, "max": 20.0,
                        "uniform": "u_light_z", "label": "light z"},
            "intensity": {"type": "float", "default": LIGHT_INTENSITY, "min": 0.0, "max": 200.0,
                          "uniform": "u_light_intensity", "label": "light intensity"},
            "ambient": {"type": "float", "default": AMBIENT, "min": 0.0, "max": 2.0, "uniform": "u_ambient",
                        "label": "ambient"},
            "lut_filter": {"type": "choice", "default": "exact", "choices": ["exact", "fast"],
                           "codegen": "lut_filter", "label": "LUT filtering"},
        },
        "requires": {"gl": 330},
        "notes": "--set view=N: " + ", ".join(f"{v} {k}" for k, v in VIEWS.items())
                 + "; split: independent (lambda 0) left | end-to-end right",
        "labels": [
            {"text": "independent (lambda 0)", "at": [0.25, 0.95], "when": {"view": VIEWS["split"]}},
            {"text": "end-to-end", "at": [0.75, 0.95], "when": {"view": VIEWS["split"]}},
            {"line": [[0.5, 0.0], [0.5, 1.0]], "when": {"view": VIEWS["split"]}},
            {"text": "end-to-end", "at": [0.5, 0.95], "when": {"view": VIEWS["end_to_end"]}},
            {"text": "independent (lambda 0)", "at": [0.5, 0.95], "when": {"view": VIEWS["independent"]}},
            {"text": "reference (16 footprint samples, analytic Disney)", "at": [0.5, 0.95],
             "when": {"view": VIEWS["reference"]}},
            {"text": "uncompressed + mips (GL trilinear), DI Disney", "at": [0.5, 0.95],
             "when": {"view": VIEWS["trilinear"]}},
            {"text": "uncompressed + mips (GL trilinear), analytic Disney", "at": [0.5, 0.95],
             "when": {"view": VIEWS["analytic"]}},
        ],
    }


def write_set_textures(out: Path, image: np.ndarray):
    """set0.png (lanes 0-3) and set1.png (lanes 4-7): the uncompressed set as two RGBA8 PNGs (image
    orientation, values as stored) for the reference view (GL mips, REPEAT)."""
    from PIL import Image

    from inshade.files import atomic_files

    data = np.rint(np.clip(image, 0, 1) * 255).astype(np.uint8)
    for i in range(2):
        with atomic_files(out / f"set{i}.png") as tmp:
            Image.fromarray(np.ascontiguousarray(data[..., 4 * i:4 * i + 4]), "RGBA").save(tmp, format="PNG")


def write_asset(out, runs, decoder, image, e2e: str, provenance: dict, metrics: dict,
                preview_size=VIEW_SIZE) -> Path:
    from inshade.runtime.image_io import write_png
    from inshade.runtime.renderer import SceneRenderer
    from inshade.runtime.scene import load_scene

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    for r in runs:
        r.graph.export(KIND, lambda_folder(r.lam), provenance={**provenance, "lambda": r.lam},
                       metrics={k: v for k, v in r.metrics.items() if k != "history"}).save(out / lambda_folder(r.lam))
    decoder.export(DECODER_KIND, "brdf", provenance={
        "source": "trained/di_brdf_disney decoders (frozen) + its encoders' rows at anisotropic = "
                  "subsurface = metallic = sheen = 0, clearcoat_gloss = 1"}).save(out / "brdf")
    write_set_textures(out, image)
    lam = next(r.lam for r in runs if lambda_folder(r.lam) == e2e)
    title = f"DI shading pipeline (bricks): independent | end-to-end (lambda {lam:g})"
    atomic_write(out / "scene.json", json.dumps(scene_dict(out.name, title, e2e, preview_size), indent=2) + "\n")
    scene = load_scene(out)
    r = SceneRenderer(scene)
    try:
        r.render(scene.make_camera(), *preview_size)
        write_png(out / "preview.png", r.read()[..., :3])
    finally:
        r.release()
    return out


# ---------------------------------------------------------------------------------------------
# command line

def add_arguments(p: argparse.ArgumentParser) -> argparse.ArgumentParser:
    d = DEFAULTS
    asset_folder.add_arguments(p, "di_shading_bricks")
    p.add_argument("--preset", choices=sorted(PRESETS), default="quick",
                   help="ship: exactly what built trained/di_shading_bricks; quick: a small run; options "
                        "given explicitly override it (default %(default)s)")
    p.add_argument("--size", type=int, help="bricks set size (power of two >= 32; default: the preset's)")
    p.add_argument("--ratio", type=float, default=d["ratio"], help="compression vs the 8-lane RGBA8 base level")
    p.add_argument("--n-cascaded", type=int, default=d["n_cascaded"], help="N_c (multiple of 4)")
    p.add_argument("--steps", type=int, help="training steps per lambda (default: the preset's)")
    p.add_argument("--lr", type=float, default=d["lr"])
    p.add_argument("--batch", type=int, default=d["batch"])
    p.add_argument("--samples", type=int, help="training pixels (default: the preset's)")
    p.add_argument("--views", type=int, help="random grazing views the pixels come from (default: the preset's)")
    p.add_argument("--metal-clip", type=float, default=d["metal_clip"],
                   help="per-sample gradient-norm bound (x 1/batch) through the GGX (metallic) lobe; 0: off")
    p.add_argument("--lambdas", type=float, nargs="+", default=d["lambdas"], help="the sweep (must include 0)")
    p.add_argument("--seed", type=int, default=d["seed"])
    p.add_argument("--brdf", default=DEFAULT_BRDF, help="the frozen di_brdf_disney asset (default %(default)s)")
    add_device_argument(p)
    return p


def run(args, argv=None) -> int:
    device = resolve_device(args.device)     # first: a missing CUDA device fails before any work
    args.out = str(asset_folder.claim(args.out, "di_shading_bricks", force=args.force))
    preset = PRESETS[args.preset]
    for k in ("size", "steps", "samples", "views"):
        if getattr(args, k) is None:
            setattr(args, k, preset.get(k, DEFAULTS[k]))
    settings = {k: getattr(args, k) for k in SETTINGS}
    settings["lambdas"] = [float(x) for x in settings["lambdas"]]
    argv = list(sys.argv[1:] if argv is None else argv)
    cmd = shlex.join(["inshade", "train", "di_shading", *argv])
    torch.set_num_threads(1)
    t0 = time.perf_counter()
    kw = {k: v for k, v in settings.items()}
    kw["metal_clip"] = kw["metal_clip"] or None
    runs, decoder, image, info = train_sweep(**kw, brdf_folder=args.brdf, name=Path(args.out).name, device=device)
    best = best_run(runs)
    sweep = [{k: v for k, v in r.metrics.items() if k != "history"} for r in runs]
    base = next(r for r in runs if r.lam == 0.0).metrics["psnr_shaded_vs_reference"]
    metrics = {"command": cmd, "preset": args.preset, "settings": settings, "device": str(device), **info,
               "lambda_best": best.lam, "sweep": sweep,
               "psnr_gain_best_vs_independent_db": round(best.metrics["psnr_shaded_vs_reference"] - base, 4),
               "psnr_gain_best_vs_independent_percent": round(
                   100.0 * (best.metrics["psnr_shaded_vs_reference"] / base - 1.0), 3),
               "train_seconds_total": round(time.perf_counter() - t0, 2),
               "note": "psnr_*: torch, 8-bit samplers, held-out plane pixels, display domain sRGB(clamp(x)); "
                       "the GLSL-rendered numbers are inshade bench di_shading's"}
    prov = {"command": cmd, "torch": torch.__version__, "device": str(device),
            "date_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
            "technique": "Differentiable Indirection end-to-end shading (Datta et al. 2023 supp. 1.5): "
                         "footprint sampler trained through the frozen DI Disney decoder"}
    out = write_asset(args.out, runs, decoder, image, lambda_folder(best.lam), prov, metrics)
    atomic_write(out / "metrics.json", json.dumps(metrics, indent=1) + "\n")
    rows = ", ".join(f"lambda {r.lam:g}: {r.metrics['psnr_shaded_vs_reference']:.2f} dB" for r in runs)
    print(f"wrote {out}: shaded PSNR vs the 16-sample reference (held-out pixels, torch) {rows}; "
          f"best lambda {best.lam:g} ({metrics['psnr_gain_best_vs_independent_db']:+.2f} dB), "
          f"{metrics['train_seconds_total']:.0f} s")
    return 0


def main(argv=None) -> int:
    return command.main("inshade train di_shading", __doc__, add_arguments, run, argv,
                        errors=(DeviceError, ShadingError, fp.FootprintError))
