"""Torch side of the PRT passes (Learnt Transfer, Dhawal et al. 2022): the reference renderer of shaders/passes/sdf_prt.frag,
the ground-truth renderer, and the quality measurement over an orbit.

- ``render(sdf, net, frame, uniforms, w, h, sh, shading)``: the pass in torch, float32, the
  operations of shaders/lib/sdf.glsl + lib/prt.glsl in the same order (camera, sphere tracing,
  central-difference normals, the transfer network with its input normalisation, shading). For
  parity with the GLSL (tests/techniques/prt/test_prt.py).
- ``render_ground_truth(sdf, uniforms, w, h, sh, shading, n_dirs=...)``: identical, except the
  transfer at every hit pixel is cast by rays (techniques/prt/transfer.py ``sdf_transfer``), so a
  comparison with the GL image measures the network's error alone (both are SH-truncated and lit
  by the same 16 coefficients).
- ``render_gbuffer(position, normal, net, frame, ...)``: the mesh_prt pass in torch, fed the GL
  G-buffer (rasterisation is the driver's; the network and shading after it are mirrored).
- ``quality_orbit(scene, bundle, n_views=30, size=...)``: GL image vs ground truth over an orbit,
  PSNR / SSIM / MAE for diffuse and glossy (the paper's Table 1 protocol), SDF or mesh scenes
  (mesh ground truth: ``mesh_transfer`` at the G-buffer's points).

"SDF module": anything with ``__call__(p [N, 3]) -> d [N]``, ``.albedo(p) -> [N, 3]`` and
``.scene`` with ``trace`` / ``center`` / ``radius`` (models/sdf.py SdfModule, models/network_sdf.py
NetworkSdfModule). Shading (one definition, lib/prt.glsl): diffuse ``albedo / pi * sum_k T_k L_k``,
glossy ``sum_k g_l(k) H_k y_k(R)`` with ``H_c = M_c T``; final ``kd * diffuse [+ ks * glossy]``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from inshade import metrics
from inshade.techniques.prt import SHADING_MODES
from inshade.techniques.prt.codegen import PRT_DEGREE, light_matrix
from inshade.geometry.sdf import SdfScene, f32
from inshade.sh import band_of, sh_basis

from inshade.models.sdf import SdfModule, camera_rays, normals, sh_background_t, trace
from inshade.techniques.prt.transfer_model import TransferFrame, evaluate_transfer

INV_PI = f32(1.0 / math.pi)
MESH_ALBEDO = (0.8, 0.8, 0.8)   # passes/mesh_prt.frag MESH_ALBEDO


@dataclass(frozen=True)
class PrtShading:
    """The PRT uniforms: u_shading (mode), u_phong_exponent, u_albedo (tint), u_kd, u_ks."""

    mode: str = "diffuse"
    exponent: float = 16.0
    albedo: float = 1.0
    kd: float = 1.0
    ks: float = 0.5

    def __post_init__(self):
        if self.mode not in SHADING_MODES:
            raise ValueError(f"shading mode must be one of {list(SHADING_MODES)}, got {self.mode!r}")

    @classmethod
    def from_settings(cls, values: dict, scene=None) -> "PrtShading":
        """From a SceneRenderer's setting values, read through the uniforms they drive."""
        out = {}
        targets = {"u_shading": "mode", "u_phong_exponent": "exponent", "u_albedo": "albedo", "u_kd": "kd",
                   "u_ks": "ks"}
        for name, s in (scene.settings.items() if scene is not None else ()):
            if s.binding == "uniform" and s.target in targets:
                out[targets[s.target]] = values[name]
        return cls(**out)


def sdf_module(sdf):
    """An SDF module for an analytic ``SdfScene`` (else ``sdf`` itself, e.g. a NetworkSdfModule)."""
    return SdfModule(sdf) if isinstance(sdf, SdfScene) else sdf


def surface_normals(sdf, p: torch.Tensor) -> torch.Tensor:
    """Central differences with the scene's normal_eps (lib/sdf.glsl sdf_normal) for any module."""
    return normals(sdf, p)


# shading (lib/prt.glsl, same order) -----------------------------------------------------------------
def prt_diffuse(t: torch.Tensor, coeffs: torch.Tensor) -> torch.Tensor:
    """sum_k t_k L_k [N, 3], accumulated in index order (prt_diffuse)."""
    acc = torch.zeros(t.shape[0], 3)
    for i in range(coeffs.shape[0]):
        acc = acc + coeffs[i] * t[:, i:i + 1]
    return acc


def phong_bands_f32(exponent: float, degree: int = PRT_DEGREE) -> list[float]:
    """prt_phong_bands in float32: (s + 1) M_l with the hemisphere-moment recurrence."""
    s = np.float32(exponent)
    one, two = np.float32(1.0), np.float32(2.0)
    m, g = [], []
    for l in range(degree):
        fl = np.float32(l)
        if l < 2:
            m.append(one / (s + one + fl))
        else:
            m.append((s - fl + two) / (s + fl + one) * m[l - 2])
        g.append(float((s + one) * m[l]))
    return g


def light_matrix_t(coeffs) -> torch.Tensor:
    """M [3, 16, 16] float32 (techniques/prt/codegen.py light_matrix of the float32 coefficients)."""
    return torch.from_numpy(light_matrix(np.asarray(coeffs, np.float32)).astype(np.float32))


def prt_glossy(t: torch.Tensor, r: torch.Tensor, exponent: float, m: torch.Tensor) -> torch.Tensor:
    """sum_k g_l(k) H_k y_k(r) with H_c = M_c t, per channel [N, 3] (prt_glossy)."""
    g = phong_bands_f32(exponent, PRT_DEGREE)
    y = sh_basis(r, PRT_DEGREE, torch)
    w = y * torch.tensor([g[b] for b in band_of(PRT_DEGREE)], dtype=torch.float32)
    h = torch.einsum("cki,ni->nck", m, t)              # [N, 3, 16]
    return (h * w[:, None, :]).sum(-1)


def reflect(rd: torch.Tensor, n: torch.Tensor) -> torch.Tensor:
    """GLSL reflect(I, N) = I - 2 dot(N, I) N."""
    d = n[:, 0] * rd[:, 0] + n[:, 1] * rd[:, 1] + n[:, 2] * rd[:, 2]
    return rd - (2.0 * d)[:, None] * n


def prt_shade(t, albedo, n, rd, coeffs, m, shading: PrtShading) -> torch.Tensor:
    """kd * albedo / pi * (t . L) [+ ks * glossy] (prt_shade); ``albedo`` already tinted."""
    c = albedo * prt_diffuse(t, coeffs) * INV_PI * f32(shading.kd)
    if shading.mode == "glossy":
        c = c + prt_glossy(t, reflect(rd, n), shading.exponent, m) * f32(shading.ks)
    return c


# the renderers ----------------------------------------------------------------------------------------
@dataclass
class View:
    """One traced view: rays, hits and the surface at the hit pixels."""

    width: int
    height: int
    rd: torch.Tensor           # [H*W, 3]
    hit: torch.Tensor          # [H*W] bool
    t: torch.Tensor            # [H*W]
    idx: torch.Tensor          # hit pixel indices
    p: torch.Tensor            # [M, 3] hit points
    n: torch.Tensor            # [M, 3] unit normals
    albedo: torch.Tensor       # [M, 3] scene albedo (untinted)


def trace_view(sdf, uniforms: dict, width: int, height: int) -> View:
    """Camera rays, sphere tracing, normals and albedo as lib/sdf.glsl (models/sdf.py)."""
    sdf = sdf_module(sdf)
    ro, rd = camera_rays(uniforms, width, height)
    hit, t = trace(sdf, ro, rd)
    idx = hit.nonzero().squeeze(1)
    with torch.no_grad():
        p = ro[idx] + rd[idx] * t[idx, None]
        n = surface_normals(sdf, p) if idx.numel() else p
        alb = sdf.albedo(p) if idx.numel() else p
    return View(width, height, rd, hit, t, idx, p, n, alb)


def compose(view: View, transfer: torch.Tensor, sh_coeffs, shading: PrtShading, m: torch.Tensor | None = None) -> dict:
    """Shade a traced view given the transfer [M, 16] at its hits; misses show the background
    (sh_background: the environment, Hann-windowed).
    Returns {"rgba": [H, W, 4] float32, "hit": [H, W] bool, "t": [H, W], "transfer": [H, W, 16]}."""
    coeffs = torch.as_tensor(np.asarray(sh_coeffs, np.float32))
    m = light_matrix_t(coeffs) if m is None and shading.mode == "glossy" else m
    with torch.no_grad():
        out = sh_background_t(coeffs, view.rd)
        if view.idx.numel():
            albedo = view.albedo * f32(shading.albedo)
            out[view.idx] = prt_shade(transfer, albedo, view.n, view.rd[view.idx], coeffs, m, shading)
        full_t = torch.zeros(view.rd.shape[0], transfer.shape[1] if transfer.ndim == 2 else 16)
        if view.idx.numel():
            full_t[view.idx] = transfer
    rgba = torch.cat([out, torch.ones(out.shape[0], 1)], -1)
    h, w = view.height, view.width
    return {"rgba": rgba.reshape(h, w, 4).numpy(), "hit": view.hit.reshape(h, w).numpy(),
            "t": view.t.reshape(h, w).numpy(), "transfer": full_t.reshape(h, w, -1).numpy()}


def gbuffer_view(position: np.ndarray, normal: np.ndarray, uniforms: dict, width: int, height: int,
                 albedo=MESH_ALBEDO) -> View:
    """A View from a mesh G-buffer (runtime/geometry.py MeshGBuffer.read(): data orientation, w = 1
    where covered): the rasterised surface replaces sphere tracing; rays as the mesh_prt pass."""
    pos = torch.from_numpy(np.ascontiguousarray(np.asarray(position, np.float32)[::-1]).reshape(-1, 4))
    nrm = torch.from_numpy(np.ascontiguousarray(np.asarray(normal, np.float32)[::-1]).reshape(-1, 4))
    _, rd = camera_rays(uniforms, width, height)
    hit = pos[:, 3] != 0.0
    idx = hit.nonzero().squeeze(1)
    alb = torch.tensor(albedo, dtype=torch.float32).expand(idx.numel(), 3)
    return View(width, height, rd, hit, torch.zeros(hit.shape[0]), idx, pos[idx, :3], nrm[idx, :3], alb)


def render_gbuffer(position, normal, net, frame: TransferFrame, uniforms: dict, width: int, height: int, sh_coeffs,
                   shading: PrtShading = PrtShading()) -> dict:
    """The mesh_prt pass in torch, fed the G-buffer the GL pass read (rasterisation itself is
    the driver's; everything after it is mirrored)."""
    view = gbuffer_view(position, normal, uniforms, width, height)
    return compose(view, network_transfer(view, net, frame), sh_coeffs, shading)


def network_transfer(view: View, net, frame: TransferFrame) -> torch.Tensor:
    """The transfer network at the hits (lib/prt.glsl prt_transfer)."""
    with torch.no_grad():
        if not view.idx.numel():
            return torch.zeros(0, PRT_DEGREE * PRT_DEGREE)
        return evaluate_transfer(net, frame, view.p, view.n).float()


def render(sdf, net, frame: TransferFrame, uniforms: dict, width: int, height: int, sh_coeffs,
           shading: PrtShading = PrtShading()) -> dict:
    """The sdf_prt pass in torch (see ``compose`` for the result). ``sdf``: an SdfScene or an SDF
    module; ``net``: the transfer GraphModule; ``frame``: its TransferFrame; ``uniforms``: the
    camera's (``camera.uniforms(w, h)``); ``sh_coeffs``: float32 [16, 3] radiance SH."""
    view = trace_view(sdf, uniforms, width, height)
    return compose(view, network_transfer(view, net, frame), sh_coeffs, shading)


def ground_truth_transfer(geometry, view: View, n_dirs: int = 256, seed: int = 0,
                          progress: bool = False) -> torch.Tensor:
    """Ray-cast transfer [M, 16] at the hits of a view (techniques/prt/transfer.py): ``geometry`` is an
    SDF (scene or module: sdf_transfer) or a trimesh.Trimesh (mesh_transfer)."""
    from inshade.techniques.prt.transfer import mesh_transfer, sdf_transfer

    if not view.idx.numel():
        return torch.zeros(0, PRT_DEGREE * PRT_DEGREE)
    if hasattr(geometry, "faces") and hasattr(geometry, "vertices"):
        return mesh_transfer(geometry, view.p, view.n, n_dirs=n_dirs, seed=seed, progress=progress).float()
    return sdf_transfer(sdf_module(geometry), view.p, view.n, n_dirs=n_dirs, seed=seed, progress=progress).float()


def render_ground_truth(sdf, uniforms: dict, width: int, height: int, sh_coeffs,
                        shading: PrtShading = PrtShading(), n_dirs: int = 256, seed: int = 0,
                        progress: bool = False) -> dict:
    """``render`` with the transfer of every hit pixel ray-cast instead of predicted."""
    view = trace_view(sdf, uniforms, width, height)
    return compose(view, ground_truth_transfer(sdf, view, n_dirs, seed, progress), sh_coeffs, shading)


# quality over an orbit ------------------------------------------------------------------------------
def image_metrics(image: np.ndarray, reference: np.ndarray, mask: np.ndarray | None = None) -> dict:
    """Linear RGB clipped to [0, 1] (peak 1). ``psnr`` and ``mae`` over the surface pixels
    (``mask``, the reference's hits; the environment background is identical in both renders and
    would inflate them), ``psnr_image`` over the whole image, ``ssim`` over the whole image (it
    needs spatial windows)."""
    a = np.clip(np.asarray(image, np.float64)[..., :3], 0.0, 1.0)
    b = np.clip(np.asarray(reference, np.float64)[..., :3], 0.0, 1.0)
    sel = np.ones(a.shape[:2], bool) if mask is None else np.asarray(mask, bool)
    if not sel.any():
        sel = np.ones(a.shape[:2], bool)

    return {"psnr": metrics.psnr(a, b, mask=sel), "ssim": metrics.ssim(a, b),
            "mae": float(np.mean(np.abs(a[sel] - b[sel]))), "psnr_image": metrics.psnr(a, b),
            "surface_pixels": int(sel.sum())}


def orbit_cameras(scene, n_views: int) -> list[dict]:
    """``n_views`` cameras evenly spaced in yaw around the scene camera's target (same distance,
    pitch and field of view)."""
    base = dict(scene.camera)
    if base.get("type") != "orbit":
        raise ValueError(f"scene '{scene.name}': quality_orbit needs an orbit camera, got {base.get('type')!r}")
    yaw0 = float(base.get("yaw", 0.0))
    return [{**base, "yaw": yaw0 + 360.0 * i / n_views} for i in range(n_views)]


def scene_geometry(scene):
    """What the ground truth casts rays against: an SdfModule (analytic ``"sdf"``), a
    NetworkSdfModule (``"sdf": {"network": ...}``) or the trimesh (``"mesh"``) of a viewer Scene."""
    from inshade.scene.description import NetworkSdfRef

    if isinstance(scene.sdf, NetworkSdfRef):
        from inshade.bundle import load

        from inshade.models.network_sdf import NetworkSdfModule
        return NetworkSdfModule.from_bundle(load(scene.sdf.bundle))
    if scene.sdf is not None:
        return sdf_module(scene.sdf)
    if scene.mesh is not None:
        return scene.mesh.data
    raise ValueError(f"scene '{scene.name}': no SDF or mesh geometry")


def quality_orbit(scene, bundle=None, n_views: int = 30, size: int = 128, *, settings: dict | None = None,
                  n_dirs: int = 256, seed: int = 0, ctx=None, cache=None, progress: bool | None = None,
                  geometry=None, albedo_view: tuple[str, str, str] | None = None) -> dict:
    """GL image (the scene's PRT pass through SceneRenderer) vs the ground-truth render over
    ``n_views`` orbit views (yaw evenly spaced), diffuse and glossy. ``scene``: a viewer Scene (or
    what load_scene takes) of a PRT pass (SDF or mesh); ``bundle`` overrides its transfer bundle;
    ``geometry`` the ray-cast geometry (default ``scene_geometry(scene)``); ``ctx``/``cache``: GL
    context and ProgramCache for the SceneRenderer. The ground truth uses
    the GL run's own surface for meshes (G-buffer) and the torch sphere trace for SDFs.
    ``albedo_view`` (setting, shaded value, albedo value): a pass whose albedo varies over the
    surface (passes/mesh_prt_gltf.frag: a glTF file's base colour) is measured with the setting at
    the shaded value, and one render per view at the albedo value gives each pixel the albedo its
    ground truth is shaded with (float32, as the pass reads it). Returns
    {"diffuse": {"psnr", "ssim", "mae", "views": [...]}, "glossy": {...}, "n_views", "size",
    "n_dirs", "gl_renderer"}; metrics as ``image_metrics``, averaged over views."""
    from tqdm import tqdm

    from inshade.scene.camera import camera_from_dict
    from inshade.runtime.render import read_rgba
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import Scene, load_scene

    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    geometry = geometry if geometry is not None else scene_geometry(scene)
    shading_setting = next((n for n, s in scene.settings.items()
                            if s.binding == "uniform" and s.target == "u_shading"), None)
    if shading_setting is None:
        raise ValueError(f"scene '{scene.name}': no setting bound to u_shading (diffuse/glossy)")
    renderer = SceneRenderer(scene, ctx, cache=cache, settings=settings,
                             bundles=[bundle] if bundle is not None else None)
    results = {mode: [] for mode in SHADING_MODES}
    try:
        if albedo_view is not None:
            renderer.set_setting(albedo_view[0], albedo_view[1])
        sh = renderer.environment_sh()
        m = light_matrix_t(sh)
        for cam_dict in tqdm(orbit_cameras(scene, n_views), desc="orbit",
                             disable=None if progress is None else not progress):
            cam = camera_from_dict(cam_dict)
            view, gt_t = None, None
            for mode in SHADING_MODES:
                renderer.set_setting(shading_setting, mode)
                image = read_rgba(renderer.render_network(cam, size, size))
                if view is None:
                    u = cam.uniforms(size, size)
                    view = (gbuffer_view(*renderer.gbuffer.read()[:2], u, size, size) if renderer.gbuffer is not None
                            else trace_view(geometry, u, size, size))
                    if albedo_view is not None:
                        view.albedo = _albedo_at(renderer, albedo_view, cam, size, view)
                    gt_t = ground_truth_transfer(geometry, view, n_dirs, seed)
                shading = PrtShading.from_settings(renderer.values, scene)
                gt = compose(view, gt_t, sh, shading, m)
                results[mode].append(image_metrics(image, gt["rgba"], gt["hit"]))
        gl_renderer = renderer.gl["renderer"]
    finally:
        renderer.release()
    out = {"n_views": n_views, "size": size, "n_dirs": n_dirs, "gl_renderer": gl_renderer}
    for mode, rows in results.items():
        out[mode] = {k: float(np.mean([r[k] for r in rows])) for k in ("psnr", "ssim", "mae", "psnr_image")}
        out[mode]["views"] = rows
    return out


def _albedo_at(renderer, albedo_view: tuple[str, str, str], cam, size: int, view: View) -> torch.Tensor:
    """The albedo [M, 3] at the view's hits, read from a render of the pass's albedo view."""
    from inshade.runtime.render import read_rgba

    setting, shaded, albedo = albedo_view
    renderer.set_setting(setting, albedo)
    image = read_rgba(renderer.render_network(cam, size, size))
    renderer.set_setting(setting, shaded)
    rows = np.ascontiguousarray(image[..., :3], np.float32).reshape(-1, 3)[view.idx.numpy()]
    return torch.from_numpy(rows)


__all__ = ["PrtShading", "render", "render_gbuffer", "render_ground_truth", "quality_orbit", "trace_view",
           "gbuffer_view", "compose", "network_transfer", "ground_truth_transfer", "scene_geometry", "prt_diffuse",
           "prt_glossy", "prt_shade", "phong_bands_f32", "light_matrix_t", "image_metrics", "orbit_cameras"]
