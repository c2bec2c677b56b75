"""The shading half of the end-to-end DI shading pipeline (train.py): the frozen DI Disney decoder
as a bundle graph, and the torch twins of lib/di_shading.glsl -- plane geometry, the visible normal
and local frame, the analytic and learned (DI decoder + glue) shading, the metallic-path clipped
shading, the display transform, and the 16-sample appearance-filtered reference.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from inshade.components.dense.torch_twin import Dense
from inshade.components.lookup_array.torch_twin import LookupArray
from inshade.models import brdf
from inshade.models import footprint_sampler as fp
from inshade.models import pbr_lanes
from inshade.models.disney_glue import disney_glue
from inshade.models.display import srgb_display
from inshade.models.graph import GraphModule

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
# the glue's per-texel scalars at those constants (techniques/di_brdf/model.py DisneyDI.extras):
# R0 specular specular_tint, R0 specular (1 - specular_tint), clearcoat / 4
K_EXTRA = (0.0, float(np.float32(brdf.R0 * 0.5)), 0.0)
SUB = (-0.375, -0.125, 0.125, 0.375)     # 4x4 footprint sample grid (pixel units)
DEFAULT_BRDF = "trained/di_brdf_disney"
REPO = Path(__file__).resolve().parents[2]


class ShadingError(ValueError):
    """A setting or input the end-to-end trainer cannot use; the message names it."""


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
    """lib/pbr_set pbr_set_unpack of 8 lanes [N, 8] (models/pbr_lanes.py `unpack`)."""
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
    """di_shading_learned: the frozen DI Disney decoder + glue (models/disney_glue.py), linear [N, 3].
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
