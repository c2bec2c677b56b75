"""Texture-space PRT, the paper's baseline (Learnt Transfer, Dhawal et al. 2022 5.1, Table 1): transfer
vectors baked into a texture on a uv-mapped mesh, shaded with the same diffuse + triple-product glossy
formulation as the learnt transfer (shaders/lib/prt.glsl). Only where the 16 coefficients come from
differs: a bilinear texture fetch at the pixel's uv instead of the MLP at (p, n).

    python -m inshade.techniques.prt.texture_prt --mesh trained/prt_mesh/mesh.ply --force --out trained/prt_mesh_texture

Steps (timed, recorded in ``OUT/metrics.json`` with the preset and its resolved settings):

1. **atlas** (``atlas``): xatlas charts + packing for a ``resolution``^2 texture with ``padding``
   texels between charts (bilinear-safe), uv rescaled to the lookup-array texel convention
   (corner-aligned: cell i is at uv i / (N - 1); models/lookup_array.py); written as ``OUT/mesh.obj``
   (positions exactly the input's, so the G-buffer surface and the ray-cast geometry are the same);
2. **bake** (``bake``): every cell whose centre lies in a uv triangle is that triangle's surface point
   (barycentric position, barycentric shading normal: what the G-buffer interpolates); cells within
   ``gutter`` cells outside every triangle (the dilation that keeps bilinear filtering from reading
   empty cells) take the closest point of the nearest triangle; each point's transfer is
   techniques/prt/transfer.py ``mesh_transfer`` (same estimator, same rays, same offset as the
   learnt transfer's training data);
3. **bundle** (kind ``prt_texture``, ``OUT/transfer``): one 2D ``lookup_array`` of 16 channels
   (8/16-bit per-channel affine quantisation, or 32-bit float) read by passes/mesh_prt_texture.frag;
4. **scene**, previews, **quality** (techniques/prt/twin.py ``quality_orbit``: the GL image vs the
   ray-cast truth at the G-buffer's points over an orbit, the protocol of the learnt assets).

Torch twin of the pass: ``render_gbuffer_texture`` (the lookup is GraphModule.from_bundle, i.e.
models/lookup_array.py ``multilinear``; shading twin.py ``compose``).

Memory: ``texture_bytes(resolution, bits)`` = N^2 x 16 lanes x bits / 8 (+ 128 bytes of scale/offset
when quantised); vertex storage is ``vertex_bytes(V)`` = V x 16 x 4.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import shlex
import time
from pathlib import Path

import numpy as np
import torch

from inshade import asset_folder, command
from inshade.devices import DeviceError, resolve_device
from inshade.files import atomic_write
from inshade.techniques.prt.texture_codegen import KIND, PREFIX, PROGRAM

COEFFS = 16
BITS = (8, 16, 32)
VERSION = 1        # of the bake; part of the cache key


class TextureBakeError(ValueError):
    """Bad input to the texture bake; the message names the argument."""


# the atlas ------------------------------------------------------------------------------------------
def atlas(mesh, resolution: int, padding: int = 2):
    """A copy of ``mesh`` (trimesh.Trimesh) with xatlas uv for a ``resolution``^2 texture: charts
    packed with ``padding`` texels between them, scaled down until one atlas of at most
    resolution x resolution texels holds them, uv in the lookup-array convention (cell i at
    i / (N - 1)). Positions are the input's; vertices are split along chart seams only.
    Deterministic (xatlas is, for a given mesh and options)."""
    import trimesh
    import xatlas

    resolution, padding = _positive(resolution, "resolution", 4), _positive(padding, "padding", 0)
    v = np.ascontiguousarray(mesh.vertices, np.float32)
    f = np.ascontiguousarray(mesh.faces, np.uint32)
    tpu = 0.0
    for _ in range(8):
        a = xatlas.Atlas()
        a.add_mesh(v, f)
        pack = xatlas.PackOptions()
        pack.resolution, pack.padding, pack.bilinear = resolution, padding, True
        if tpu:
            pack.texels_per_unit = tpu
        a.generate(xatlas.ChartOptions(), pack)
        w, h = int(a.width), int(a.height)
        if a.atlas_count == 1 and max(w, h) <= resolution:
            break
        tpu = float(a.texels_per_unit) * min(0.97, resolution / max(w, h, 1))
    else:
        raise TextureBakeError(f"resolution: xatlas could not pack the mesh into one {resolution}^2 atlas")
    vmap, idx, uv = a[0]
    texel = np.asarray(uv, np.float64) * [w, h] - 0.5              # texel-centre units, cell i at i
    uv_lut = np.clip(texel / (resolution - 1), 0.0, 1.0)
    out = trimesh.Trimesh(np.asarray(mesh.vertices, np.float64)[vmap], np.asarray(idx, np.int64),
                          visual=trimesh.visual.TextureVisuals(uv=uv_lut), process=False)
    out.metadata["atlas"] = {"resolution": resolution, "padding": padding, "width": w, "height": h,
                             "charts": int(a.chart_count), "utilization": float(a.utilization),
                             "texels_per_unit": float(a.texels_per_unit)}
    return out


def _positive(v, name, low=1):
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < low:
        raise TextureBakeError(f"{name}: must be an int >= {low}, got {v!r}")
    return int(v)


def face_charts(mesh) -> np.ndarray:
    """Chart id [F] of every face: faces sharing a (uv-split) vertex are one chart."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    f = np.asarray(mesh.faces)
    nf, nv = len(f), len(mesh.vertices)
    rows = np.repeat(np.arange(nf), 3)
    m = coo_matrix((np.ones(3 * nf), (rows, f.reshape(-1))), shape=(nf, nv)).tocsr()
    _, labels = connected_components(m @ m.T, directed=False)
    return labels


# texel -> surface points ---------------------------------------------------------------------------
def texel_samples(mesh, resolution: int, gutter: float = 1.5) -> dict:
    """The surface point of every texture cell that bilinear filtering can read: cells whose centre
    is inside a uv triangle (``inside``; barycentric coordinates of that triangle) and cells within
    ``gutter`` cells of one (the closest point of the nearest triangle). Ties go to the lower face
    index. Returns {"cell" [M] flat index iy * N + ix, "face" [M], "bary" [M, 3] float64, "inside"
    [M] bool, "dist" [M] (cells)}."""
    from inshade.geometry.mesh import mesh_uv

    n = _positive(resolution, "resolution", 2)
    uv = mesh_uv(mesh)
    if uv is None:
        raise TextureBakeError("mesh: has no texture coordinates (run atlas() first)")
    c = uv * (n - 1)                                                         # cell units
    f = np.asarray(mesh.faces)
    tri = c[f]                                                               # [F, 3, 2]
    lo = np.clip(np.floor(tri.min(1) - gutter), 0, n - 1).astype(np.int64)
    hi = np.clip(np.ceil(tri.max(1) + gutter), 0, n - 1).astype(np.int64)
    nx, ny = hi[:, 0] - lo[:, 0] + 1, hi[:, 1] - lo[:, 1] + 1
    count = nx * ny
    face = np.repeat(np.arange(len(f)), count)
    local = np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)
    ix = lo[face, 0] + local % nx[face]
    iy = lo[face, 1] + local // nx[face]
    p = np.stack([ix, iy], -1).astype(np.float64)
    a, b, cc = tri[face, 0], tri[face, 1], tri[face, 2]
    bary, dist = _closest_barycentric(p, a, b, cc)
    keep = dist <= gutter
    cell = (iy * n + ix)[keep]
    face, bary, dist = face[keep], bary[keep], dist[keep]
    order = np.lexsort((face, dist, cell))
    cell, face, bary, dist = cell[order], face[order], bary[order], dist[order]
    first = np.ones(len(cell), bool)
    first[1:] = cell[1:] != cell[:-1]
    return {"cell": cell[first], "face": face[first], "bary": bary[first], "inside": dist[first] == 0.0,
            "dist": dist[first], "resolution": n}


def _closest_barycentric(p, a, b, c):
    """Barycentric coordinates [M, 3] of the closest point of 2D triangles (a, b, c) to p, and the
    distance [M] (0 inside)."""
    v0, v1, v2 = b - a, c - a, p - a
    den = v0[:, 0] * v1[:, 1] - v1[:, 0] * v0[:, 1]
    den = np.where(np.abs(den) > 1e-30, den, 1e-30)
    l1 = (v2[:, 0] * v1[:, 1] - v1[:, 0] * v2[:, 1]) / den
    l2 = (v0[:, 0] * v2[:, 1] - v2[:, 0] * v0[:, 1]) / den
    bary = np.stack([1.0 - l1 - l2, l1, l2], -1)
    inside = (bary >= 0.0).all(-1)
    best_d = np.full(len(p), np.inf)
    best = np.zeros_like(bary)
    for i, j in ((0, 1), (1, 2), (2, 0)):
        pa, pb = (a, b, c)[i], (a, b, c)[j]
        e = pb - pa
        t = np.clip(np.einsum("mk,mk->m", p - pa, e) / np.maximum(np.einsum("mk,mk->m", e, e), 1e-30), 0.0, 1.0)
        d = np.linalg.norm(pa + t[:, None] * e - p, axis=-1)
        better = d < best_d
        cand = np.zeros_like(bary)
        cand[:, i], cand[:, j] = 1.0 - t, t
        best = np.where(better[:, None], cand, best)
        best_d = np.where(better, d, best_d)
    return np.where(inside[:, None], bary, best), np.where(inside, 0.0, best_d)


def sample_points(mesh, samples: dict):
    """Surface positions and unit shading normals (float32 tensors) of ``texel_samples``: what the
    G-buffer interpolates (geometry/mesh.py shading_normals, welded across uv seams)."""
    from inshade.geometry.mesh import shading_normals

    f = np.asarray(mesh.faces)[samples["face"]]
    w = samples["bary"]
    pos = np.einsum("mc,mcx->mx", w, np.asarray(mesh.vertices, np.float64)[f])
    nrm = np.einsum("mc,mcx->mx", w, shading_normals(mesh)[f])
    length = np.linalg.norm(nrm, axis=-1, keepdims=True)
    nrm = np.where(length > 1e-12, nrm / np.maximum(length, 1e-300), np.asarray(mesh.face_normals)[samples["face"]])
    return torch.from_numpy(pos.astype(np.float32)), torch.from_numpy(nrm.astype(np.float32))


def bake(mesh, resolution: int, n_dirs: int = 256, seed: int = 0, gutter: float = 1.5, progress=None,
         cache_dir=None) -> tuple[np.ndarray, dict]:
    """The transfer texture [N, N, 16] float32 (image layout: row iy, column ix) of a uv-mapped
    mesh, and bake statistics. Cells no filter footprint reaches stay 0. ``cache_dir``: the
    table is stored there keyed by mesh + settings and read back by a later call."""
    from inshade.techniques.prt.transfer import MESH_OFFSET, VERSION as TRANSFER_VERSION, mesh_transfer
    from inshade.techniques.prt.transfer_dataset import geometry_digest
    from inshade.geometry.mesh import mesh_uv

    n = _positive(resolution, "resolution", 2)
    n_dirs = _positive(n_dirs, "n_dirs")
    key_src = json.dumps({"v": VERSION, "transfer": TRANSFER_VERSION, "offset": MESH_OFFSET, "n": n,
                          "dirs": n_dirs, "seed": int(seed), "gutter": float(gutter)}, sort_keys=True)
    h = hashlib.sha256((geometry_digest(mesh) + key_src).encode())
    h.update(np.ascontiguousarray(mesh_uv(mesh), np.float64).tobytes())
    key = h.hexdigest()[:24]
    path = Path(cache_dir) / f"texture-{key}.safetensors" if cache_dir is not None else None
    if path is not None and path.is_file():
        from safetensors.numpy import load_file
        from safetensors import safe_open

        with safe_open(str(path), framework="np") as fh:
            stats = json.loads(fh.metadata()["stats"])
        return load_file(str(path))["table"], {**stats, "cached": True}
    start = time.perf_counter()
    s = texel_samples(mesh, n, gutter)
    pos, nrm = sample_points(mesh, s)
    t0 = time.perf_counter()
    transfer = mesh_transfer(mesh, pos, nrm, n_dirs=n_dirs, seed=seed, progress=progress).numpy()
    ray_seconds = time.perf_counter() - t0
    table = np.zeros((n * n, COEFFS), np.float32)
    table[s["cell"]] = transfer
    table = table.reshape(n, n, COEFFS)
    stats = {"resolution": n, "n_dirs": n_dirs, "seed": int(seed), "gutter": float(gutter), "key": key,
             "cells_inside": int(s["inside"].sum()), "cells_gutter": int((~s["inside"]).sum()),
             "coverage": round(float(s["inside"].sum()) / (n * n), 4), "rays": int(len(s["cell"]) * n_dirs),
             "seconds": round(time.perf_counter() - start, 2), "ray_seconds": round(ray_seconds, 2), "cached": False}
    if path is not None:
        from safetensors.numpy import save_file
        from inshade.files import atomic_files

        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_files(path) as tmp:
            save_file({"table": table}, str(tmp), metadata={"stats": json.dumps(stats, sort_keys=True)})
    return table, stats


def bleed_check(mesh, resolution: int, samples: dict, n_points: int = 20000, seed: int = 0) -> dict:
    """Bilinear footprints of random surface points (area-weighted, uniform barycentrics) that read
    a cell baked for another chart, or no cell at all: both must be 0 for a bleed-free atlas."""
    import trimesh

    from inshade.geometry.mesh import mesh_uv

    n = int(resolution)
    charts = face_charts(mesh)
    _, fi, bary = trimesh.sample.sample_surface(mesh, n_points, seed=int(seed), return_barycentric=True)
    uv = np.einsum("mc,mcx->mx", bary, mesh_uv(mesh)[np.asarray(mesh.faces)[fi]]) * (n - 1)
    i0 = np.clip(np.floor(uv), 0, n - 2).astype(np.int64)
    owner = np.full(n * n, -1)
    owner[samples["cell"]] = charts[samples["face"]]
    other = empty = 0
    for dx in (0, 1):
        for dy in (0, 1):
            o = owner[(i0[:, 1] + dy) * n + i0[:, 0] + dx]
            empty += int((o < 0).sum())
            other += int(((o >= 0) & (o != charts[fi])).sum())
    return {"points": int(n_points), "footprint_cells_other_chart": other, "footprint_cells_empty": empty}


# the bundle -----------------------------------------------------------------------------------------
def texture_graph(table: np.ndarray, bits: int = 16):
    """GraphModule uv[2] -> transfer[16]: one 2D lookup array holding ``table`` [N, N, 16]."""
    from inshade.components.lookup_array.torch_twin import LookupArray
    from inshade.models import GraphModule

    table = np.asarray(table, np.float32)
    if table.ndim != 3 or table.shape[0] != table.shape[1] or table.shape[2] != COEFFS:
        raise TextureBakeError(f"table: must be [N, N, {COEFFS}], got {list(table.shape)}")
    if bits not in BITS:
        raise TextureBakeError(f"bits: must be one of {list(BITS)}, got {bits!r}")
    n = table.shape[0]
    g = GraphModule([("uv", 2, "uv")])
    g.add("transfer", LookupArray([n, n], COEFFS, bits=bits, init=torch.from_numpy(table)), "uv")
    g.output("transfer", "transfer", "sh_transfer")
    return g


def texture_bundle(table: np.ndarray, bits: int, name: str, bake_info: dict, provenance: dict | None = None):
    """The ``prt_texture`` bundle of a baked table (cells quantised to ``bits`` on export)."""
    g = texture_graph(table, bits)
    render = {"transfer_texture": {"resolution": int(table.shape[0]), "bits": int(bits), "degree": 4,
                                   "bytes": texture_bytes(table.shape[0], bits), **bake_info}}
    return g.export(KIND, name, provenance=provenance or {}, render=render)


def texture_bytes(resolution: int, bits: int) -> int:
    """Bytes of a transfer texture: N^2 cells x 16 lanes x bits / 8, plus the per-channel scale and
    offset (2 x 16 float32) when quantised."""
    return int(resolution) ** 2 * COEFFS * int(bits) // 8 + (0 if bits == 32 else 2 * COEFFS * 4)


def vertex_bytes(vertices: int, bytes_per_lane: int = 4) -> int:
    """Per-vertex transfer storage: V x 16 lanes (float32 by default)."""
    return int(vertices) * COEFFS * int(bytes_per_lane)


# the torch twin of the pass -------------------------------------------------------------------------
def texture_transfer(graph, uv) -> torch.Tensor:
    """lib/prt_texture.glsl prt_texture_transfer: the lookup at uv [M, 2] -> [M, 16]."""
    with torch.no_grad():
        uv = torch.as_tensor(np.asarray(uv, np.float32))
        if uv.shape[0] == 0:
            return torch.zeros(0, COEFFS)
        return graph(uv).float()


def render_gbuffer_texture(position, normal, uv, graph, uniforms: dict, width: int, height: int, sh_coeffs,
                           shading=None) -> dict:
    """passes/mesh_prt_texture.frag in torch, fed the G-buffer the GL pass read (position, normal,
    uv as MeshGBuffer.read() returns them); result as twin.py ``compose``."""
    from inshade.techniques.prt.twin import PrtShading, compose, gbuffer_view

    view = gbuffer_view(position, normal, uniforms, width, height)
    uvs = np.ascontiguousarray(np.asarray(uv, np.float32)[::-1]).reshape(-1, 4)[view.idx.numpy(), :2]
    return compose(view, texture_transfer(graph, uvs), sh_coeffs, shading or PrtShading())


# the asset ------------------------------------------------------------------------------------------
SHIP_BASE = dict(resolution=512, bits=8, dirs=256, padding=2, gutter=1.5, seed=0, quality_views=30,
                 quality_size=96, quality_dirs=512, camera_from=None, title="")
SHIP_ASSETS = {
    "prt_mesh_texture": {**SHIP_BASE, "camera_from": "trained/prt_mesh/scene.json",
                         "title": "PRT baseline: the procedural bunny, transfer baked into a 512^2 8-bit texture"},
}
QUICK = {**SHIP_BASE, "resolution": 128, "dirs": 16, "quality_views": 2, "quality_size": 32, "quality_dirs": 32}
PRESETS = ("quick", "ship")
SETTINGS = tuple(SHIP_BASE)
MESH_NAME = "mesh.obj"


def preset_settings(preset: str, name: str) -> dict:
    """What ``--preset`` gives an asset folder called ``name`` (before explicit options)."""
    if preset == "quick":
        return dict(QUICK)
    if preset == "ship":
        return dict(SHIP_ASSETS.get(name, SHIP_BASE))
    raise ValueError(f"--preset: expected one of {', '.join(PRESETS)}, got {preset!r}")


def scene_dict(name: str, title: str, camera: dict, bookmarks: dict) -> dict:
    """scene.json of a texture PRT asset: the learnt mesh scene's (train.py) with this pass."""
    from inshade.techniques.prt.train import PRT_SETTINGS, scene_dict as prt_scene

    scene = prt_scene("mesh", MESH_NAME, name, title, camera, bookmarks)
    settings = {k: v for k, v in PRT_SETTINGS.items() if k != "storage"}
    settings["lut_filter"] = {"type": "choice", "default": "exact", "choices": ["exact", "fast"],
                              "codegen": "lut_filter", "label": "texture filter"}
    return {**scene, "program": PROGRAM, "networks": [{"bundle": "transfer", "prefix": PREFIX}],
            "settings": settings}


def add_arguments(p: argparse.ArgumentParser) -> argparse.ArgumentParser:
    p.add_argument("--mesh", required=True, help="triangle mesh (OBJ/PLY/GLB); its uv are replaced by an atlas")
    asset_folder.add_arguments(p, "prt_<mesh>_texture")
    p.add_argument("--preset", choices=PRESETS, default="ship",
                   help="settings: ship = what built the shipped asset OUT is named after (else the base recipe), "
                        "quick = seconds; options given explicitly override the preset")
    p.add_argument("--resolution", type=int, help="texture side N (cells)")
    p.add_argument("--bits", type=int, choices=BITS, help="bits per lane (8/16: per-channel affine; 32: float)")
    p.add_argument("--dirs", type=int, help="rays per texel")
    p.add_argument("--padding", type=int, help="texels between charts (xatlas)")
    p.add_argument("--gutter", type=float, help="cells outside the charts baked (closest point), in cells")
    p.add_argument("--seed", type=int)
    p.add_argument("--quality-views", type=int)
    p.add_argument("--quality-size", type=int)
    p.add_argument("--quality-dirs", type=int)
    p.add_argument("--camera-from", help="take camera and bookmarks from this scene.json")
    p.add_argument("--title")
    p.add_argument("--cache", default=None, help="bake cache folder (default ~/.cache/inshade/prt_texture)")
    p.add_argument("--device", default="cpu", help="auto|cpu|cuda[:N]: recorded; the bake's rays are embree's "
                                                   "(CPU) on every device")
    return p


def run(args: argparse.Namespace) -> int:
    from inshade.geometry.mesh import load_mesh, obj_text
    from inshade.techniques.prt.train import default_name, previews_and_quality, scene_camera
    from inshade.techniques.prt.transfer_dataset import geometry_bound

    device = resolve_device(args.device)
    out = asset_folder.claim(args.out, default_name(Path(args.mesh)) + "_texture", force=args.force)
    args.out = str(out)
    settings = preset_settings(args.preset, out.name)
    for k in SETTINGS:
        given = getattr(args, k, None)
        if given is not None:
            settings[k] = given
    _positive(settings["resolution"], "--resolution", 4)
    _positive(settings["dirs"], "--dirs")
    cmd = ["python", "-m", "inshade.techniques.prt.texture_prt", f"--mesh={args.mesh}", f"--out={args.out}",
           f"--preset={args.preset}"] + [f"--{k.replace('_', '-')}={getattr(args, k)}" for k in SETTINGS
                                         if getattr(args, k, None) is not None]
    times = {}
    start = time.perf_counter()
    mesh = load_mesh(args.mesh)
    out.mkdir(parents=True, exist_ok=True)
    mapped = atlas(mesh, settings["resolution"], settings["padding"])
    atomic_write(out / MESH_NAME, obj_text(mapped))
    info = mapped.metadata["atlas"]
    mesh = load_mesh(out / MESH_NAME)           # what the renderer reads (vertices merged as it merges them)
    times["atlas_seconds"] = time.perf_counter() - start
    cache = Path(args.cache) if args.cache else Path.home() / ".cache" / "inshade" / "prt_texture"
    start = time.perf_counter()
    table, stats = bake(mesh, settings["resolution"], settings["dirs"], settings["seed"], settings["gutter"],
                        progress=None, cache_dir=cache)
    samples = texel_samples(mesh, settings["resolution"], settings["gutter"])
    bleed = bleed_check(mesh, settings["resolution"], samples)
    times["bake_seconds"] = time.perf_counter() - start
    prov = {"command": shlex.join(cmd), "mesh": str(args.mesh), "device": str(device),
            "estimator": "techniques/prt/transfer.py mesh_transfer (cosine-weighted Fibonacci lattice)",
            "torch": torch.__version__}
    bundle = texture_bundle(table, settings["bits"], f"{out.name}_transfer",
                            {"atlas": info, "bake": {k: v for k, v in stats.items() if k != "cached"}, "bleed": bleed},
                            provenance=prov)
    bundle.save(out / "transfer")
    camera, bookmarks = scene_camera(*geometry_bound(mesh), settings["camera_from"])
    scene = scene_dict(out.name, settings["title"] or f"PRT baseline: {out.name}", camera, bookmarks)
    atomic_write(out / "scene.json", json.dumps(scene, indent=1) + "\n")
    quality, shown = previews_and_quality(out, settings["quality_views"], settings["quality_size"],
                                          settings["quality_dirs"])
    times.update(shown)
    metrics = {"asset": out.name, "geometry": "mesh", "technique": "texture-space PRT (baseline)",
               "command": shlex.join(cmd), "preset": args.preset, "settings": settings, "atlas": info,
               "bake": stats, "bleed": bleed, "texture_bytes": texture_bytes(settings["resolution"], settings["bits"]),
               "vertex_bytes_f32": vertex_bytes(len(mesh.vertices)), "quality": quality, **times}
    atomic_write(out / "metrics.json", json.dumps(metrics, indent=1, sort_keys=True) + "\n")
    print(json.dumps({"quality": {m: quality[m] for m in ("diffuse", "glossy")}, **times}, indent=1))
    return 0


def main(argv=None) -> int:
    from inshade.geometry.mesh import MeshError

    return command.main("python -m inshade.techniques.prt.texture_prt", __doc__, add_arguments, run, argv,
                        errors=(DeviceError, TextureBakeError, MeshError))


if __name__ == "__main__":
    raise SystemExit(main())
