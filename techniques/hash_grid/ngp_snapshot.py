"""instant-ngp NeRF snapshots (``.msgpack``, ``.ingp``) -> a hash_grid radiance-field asset that
``inshade render`` and ``inshade view`` draw.

The layout, established from instant-ngp's source (NVlabs/instant-ngp at abe236ee, 2026-02-02) and
tiny-cuda-nn's (6ee3546b); docs/tcnn.md has the tiny-cuda-nn rules:

- the file is the network config (JSON: ``encoding``, ``network``, ``dir_encoding``,
  ``rgb_network``) with a ``snapshot`` object, written by nlohmann's ``to_msgpack``; ``.ingp`` is
  the same through zlib (src/testbed.cu ``Testbed::save_snapshot``);
- ``snapshot.params_binary``: the trainer's inference parameters, ``params_type`` "__half" or
  "float", ``n_params`` of them (tiny-cuda-nn include/tiny-cuda-nn/trainer.h ``Trainer::serialize``);
- their order: density network, rgb network, position encoding, direction encoding
  (include/neural-graphics-primitives/nerf_network.h ``NerfNetwork::set_params_impl``);
- the position encoding is padded to 16 lanes when the density network is a FullyFusedMLP, else 8;
  the density network gives 16 lanes unless ``n_output_dims`` says otherwise; the rgb network takes
  [those 16 lanes, the direction encoding padded to the rgb network's alignment] and gives 3 lanes
  (the ``NerfNetwork`` constructor);
- the network sees positions as ``(p - aabb.min) / aabb.diag()`` and directions as ``(d + 1) / 2``
  (include/neural-graphics-primitives/nerf_device.cuh ``warp_position``, ``warp_direction``);
  density = exp(lane 0), colour = logistic(rgb lanes): instant-ngp's defaults
  (``network_to_density``, ``network_to_rgb``), which the snapshot does not record;
- ``snapshot.density_grid_binary``: fp16, 128^3 cells per cascade in Morton order
  (``cascaded_grid_idx_at``), cascades 0..max_cascade, max_cascade = ceil(log2(aabb_scale)); a cell
  is occupied where its value exceeds min(0.01, the mean of cascade 0's max(v, 0))
  (src/testbed_nerf.cu ``grid_to_bitfield``), and coarser cascades also hold every occupied cell of
  the finer ones (``bitfield_max_pool``). The box ``aabb`` is cascade max_cascade's region, so that
  cascade's bits, one per cell, are the asset's occupancy grid.

The asset follows the radiance field's bundle convention (radiance_field.py): density is clamped at
exp(15) as there (no visible change: a sample that dense is opaque), instant-ngp's march steps
sqrt(3)/1024 of a unit cube (nerf_device.cuh ``STEPSIZE``) and so does this one. No snapshot made by
instant-ngp itself could be produced on this machine (it needs CUDA): the tests write snapshots to
this layout here.
"""
from __future__ import annotations

import math
import zlib
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import numpy as np

GRID_SIZE = 128                  # NERF_GRIDSIZE()
MIN_OPTICAL_THICKNESS = 0.01     # NERF_MIN_OPTICAL_THICKNESS()
STEP_UNIT_CUBE = math.sqrt(3.0) / 1024.0   # STEPSIZE(): sqrt(3) / NERF_STEPS()
FORMAT_VERSION = 1               # SNAPSHOT_FORMAT_VERSION
DENSITY_LANES = 16
SUFFIXES = (".msgpack", ".ingp")


class SnapshotError(ValueError):
    """A snapshot this reader cannot take; the message names the field."""


@dataclass
class Snapshot:
    path: Path
    config: dict          # encoding, network, dir_encoding, rgb_network
    params: np.ndarray    # float32 values
    dtype: str            # "float16" | "float32": how they were stored
    aabb: np.ndarray      # [2, 3]: min, max
    aabb_scale: int
    density_grid: np.ndarray   # float32 [cascades * 128^3], Morton order per cascade
    background: tuple
    camera: dict


def _field(obj: dict, key: str, where: str):
    if not isinstance(obj, dict) or key not in obj:
        raise SnapshotError(f"{where}.{key}: missing")
    return obj[key]


def read(path) -> Snapshot:
    """The snapshot file at ``path``, checked field by field (SnapshotError names the first bad one)."""
    import msgpack

    path = Path(path)
    raw = path.read_bytes()
    if path.suffix.lower() == ".ingp":
        try:
            raw = zlib.decompress(raw, zlib.MAX_WBITS | 32)   # zlib or gzip header
        except zlib.error as exc:
            raise SnapshotError(f"(file): not a zlib stream: {exc}") from None
    try:
        doc = msgpack.unpackb(raw, raw=False, strict_map_key=False)
    except (msgpack.UnpackException, ValueError) as exc:
        raise SnapshotError(f"(file): not msgpack: {exc}") from None
    snap = _field(doc, "snapshot", "(top level)")
    version = snap.get("version", 0) if isinstance(snap, dict) else 0
    if not isinstance(version, int) or version < FORMAT_VERSION:
        raise SnapshotError(f"snapshot.version: {version!r}; instant-ngp reads version {FORMAT_VERSION} and newer")
    mode = snap.get("mode", "Nerf" if "nerf" in snap else None)
    if mode != "Nerf":
        raise SnapshotError(f"snapshot.mode: {mode!r}; only NeRF snapshots hold a radiance field")
    config = {k: _field(doc, k, "(top level)") for k in ("encoding", "network", "dir_encoding", "rgb_network")}
    params_type = snap.get("params_type", "float")
    dtypes = {"__half": ("<f2", "float16"), "float": ("<f4", "float32")}
    if params_type not in dtypes:
        raise SnapshotError(f"snapshot.params_type: {params_type!r}; instant-ngp writes \"__half\" or \"float\"")
    blob = _field(snap, "params_binary", "snapshot")
    if not isinstance(blob, (bytes, bytearray)):
        raise SnapshotError(f"snapshot.params_binary: expected binary, got {type(blob).__name__}")
    np_dtype, dtype = dtypes[params_type]
    if len(blob) % np.dtype(np_dtype).itemsize:
        raise SnapshotError(f"snapshot.params_binary: {len(blob)} bytes is no whole number of {params_type}")
    params = np.frombuffer(blob, np_dtype).astype(np.float32)
    n_params = snap.get("n_params", params.size)
    if n_params != params.size:
        raise SnapshotError(f"snapshot.n_params: {n_params}, but params_binary holds {params.size}")
    nerf = _field(snap, "nerf", "snapshot")
    aabb_scale = nerf.get("aabb_scale", 1) if isinstance(nerf, dict) else 1
    if not isinstance(aabb_scale, int) or aabb_scale < 1 or aabb_scale & (aabb_scale - 1):
        raise SnapshotError(f"snapshot.nerf.aabb_scale: {aabb_scale!r}; instant-ngp takes a power of two")
    aabb = _aabb(snap.get("aabb"), aabb_scale)
    if snap.get("density_grid_size", GRID_SIZE) != GRID_SIZE:
        raise SnapshotError(f"snapshot.density_grid_size: {snap.get('density_grid_size')!r}; instant-ngp's is "
                            f"{GRID_SIZE}")
    grid_blob = _field(snap, "density_grid_binary", "snapshot")
    if not isinstance(grid_blob, (bytes, bytearray)) or len(grid_blob) % 2:
        raise SnapshotError("snapshot.density_grid_binary: expected fp16 binary")
    grid = np.frombuffer(grid_blob, "<f2").astype(np.float32)
    cascades = max_cascade(aabb_scale) + 1
    if grid.size != cascades * GRID_SIZE ** 3:
        raise SnapshotError(f"snapshot.density_grid_binary: {grid.size} cells; aabb_scale {aabb_scale} needs "
                            f"{cascades} cascades of {GRID_SIZE}^3 = {cascades * GRID_SIZE ** 3}")
    bg = snap.get("background_color", [0.0, 0.0, 0.0, 1.0])
    background = tuple(float(v) for v in bg[:3]) if isinstance(bg, list) and len(bg) >= 3 else (0.0, 0.0, 0.0)
    camera = snap.get("camera") if isinstance(snap.get("camera"), dict) else {}
    return Snapshot(path, config, params, dtype, aabb, aabb_scale, grid, background, camera)


def _aabb(value, aabb_scale: int) -> np.ndarray:
    """instant-ngp's BoundingBox as JSON ({"min": [...], "max": [...]}); absent: the cube of side
    aabb_scale around (0.5, 0.5, 0.5) that instant-ngp makes of aabb_scale."""
    if value is None:
        half = aabb_scale / 2.0
        return np.array([[0.5 - half] * 3, [0.5 + half] * 3], np.float64)
    try:
        box = np.array([value["min"], value["max"]], np.float64)
    except (KeyError, TypeError, ValueError):
        raise SnapshotError(f"snapshot.aabb: expected {{\"min\": [x, y, z], \"max\": [x, y, z]}}, got {value!r}") \
            from None
    side = box[1] - box[0]
    if box.shape != (2, 3) or not np.all(side > 0) or not np.allclose(side, side[0], rtol=1e-6):
        raise SnapshotError(f"snapshot.aabb: {value!r} is not a cube (the radiance field's box is one)")
    return box


def max_cascade(aabb_scale: int) -> int:
    """The smallest m with 2^m >= aabb_scale (testbed_nerf.cu)."""
    return max(0, (aabb_scale - 1).bit_length())


def morton_decode(codes: np.ndarray) -> np.ndarray:
    """Morton codes -> [..., 3] (x, y, z): bit 3b + a of the code is bit b of axis a
    (tiny-cuda-nn common_device.h ``morton3D``)."""
    codes = np.asarray(codes, np.uint64)
    out = np.zeros(codes.shape + (3,), np.int64)
    for bit in range(7):   # 128 = 2^7 cells per axis
        for axis in range(3):
            out[..., axis] |= ((codes >> np.uint64(3 * bit + axis)) & np.uint64(1)).astype(np.int64) << bit
    return out


def occupancy_bits(density_grid: np.ndarray, aabb_scale: int) -> np.ndarray:
    """bool [128, 128, 128] ([k, j, i], x fastest): cascade max_cascade's occupancy, with every finer
    cascade's occupied cells pooled into it as instant-ngp does."""
    n = GRID_SIZE ** 3
    top = max_cascade(aabb_scale)
    mean = float(np.maximum(density_grid[:n], 0.0).sum() / n)
    threshold = min(MIN_OPTICAL_THICKNESS, mean)
    xyz = morton_decode(np.arange(n))
    bits = None
    for cascade in range(top + 1):
        dense = np.zeros((GRID_SIZE,) * 3, bool)   # [x, y, z]
        dense[xyz[:, 0], xyz[:, 1], xyz[:, 2]] = density_grid[cascade * n:(cascade + 1) * n] > threshold
        if bits is not None:   # the finer cascade covers this one's central half
            pooled = bits.reshape(64, 2, 64, 2, 64, 2).any(axis=(1, 3, 5))
            dense[32:96, 32:96, 32:96] |= pooled
        bits = dense
    return np.ascontiguousarray(bits.transpose(2, 1, 0))


def field_graph(snap: Snapshot):
    """The snapshot's NerfNetwork as the radiance field's graph (inputs x, d; outputs density, rgb)."""
    from inshade.convert.lowering import ConvertError
    from inshade.convert.tcnn import Builder, Cursor, lower_encoding, lower_network
    from inshade.convert.tcnn_config import Context, next_multiple, parse_encoding, parse_network
    from inshade.models import GraphModule

    ctx = Context(str(snap.path))
    cfg = snap.config
    density_cfg, rgb_cfg = dict(cfg["network"]), dict(cfg["rgb_network"])
    fully_fused = str(density_cfg.get("otype", "")).lower() in ("fullyfusedmlp", "megakernelmlp")
    pos = parse_encoding(ctx, cfg["encoding"], 3, "encoding", 16 if fully_fused else 8)
    lanes_out = density_cfg.pop("n_output_dims", DENSITY_LANES)
    if lanes_out != DENSITY_LANES:
        raise ConvertError(f"{snap.path}: network.n_output_dims: {lanes_out}; this reader takes instant-ngp's "
                           f"{DENSITY_LANES}")
    density = parse_network(ctx, density_cfg, pos.padded, DENSITY_LANES)
    rgb_alignment = 16   # minimum_alignment(): FullyFusedMLP and CutlassMLP alike
    direction = parse_encoding(ctx, cfg["dir_encoding"], 3, "dir_encoding", rgb_alignment)
    rgb_in = next_multiple(direction.padded + density.padded_output, rgb_alignment)
    if rgb_in != direction.padded + density.padded_output:
        raise ConvertError(f"{snap.path}: rgb_network: its input would hold unset lanes")
    rgb = parse_network(ctx, rgb_cfg, rgb_in, 3)
    counts = [density.n_params(), rgb.n_params(), pos.n_params(), direction.n_params()]
    if sum(counts) != snap.params.size:
        raise ConvertError(f"{snap.path}: snapshot.params_binary: {snap.params.size} parameters; the config needs "
                           f"{sum(counts)} (density network {counts[0]}, rgb network {counts[1]}, encoding "
                           f"{counts[2]}, dir_encoding {counts[3]})")
    for net in (density, rgb):
        net.check_precision(ctx, snap.dtype)
    parts = np.split(snap.params, np.cumsum(counts)[:-1])
    model = SimpleNamespace(ctx=ctx, network=density, n_input_dims=3)
    b = Builder(model)
    b.g = GraphModule([("x", 3, "position"), ("d", 3, "direction")])
    geo = lower_network(b, lower_encoding(b, pos, "x", Cursor(parts[2]), snap.dtype), Cursor(parts[0]), snap.dtype)
    warped = b.node("affine", {}, ["d"], {"scale": np.full(3, 0.5), "offset": np.full(3, 0.5)}, "dir_encoding")
    dir_lanes = lower_encoding(b, direction, warped, Cursor(parts[3]), snap.dtype)
    model.network = rgb
    raw_rgb = lower_network(b, [(geo, i) for i in range(DENSITY_LANES)] + dir_lanes, Cursor(parts[1]), snap.dtype)
    colour = b.node("sigmoid", {}, [raw_rgb], where="rgb")
    lane0 = b.node("select", {"lanes": [0]}, [geo], where="density")
    clamped = b.node("clamp", {"max": 15.0}, [lane0], where="density")
    sigma = b.node("exp", {}, [clamped], where="density")
    b.g.output("density", sigma, "density")
    b.g.output("rgb", colour, "rgb")
    return b.g


SOURCE = "an instant-ngp NeRF snapshot (.msgpack, or .ingp: zlib) -> a hash_grid radiance-field asset"
REFERENCE_SIZE = 256
REFERENCE_IMAGE = "reference/march"     # .exr (linear, the display modes) and .png (8-bit sRGB, the pass)


def march_settings(snap: Snapshot):
    """The asset's march: the snapshot's box and background, instant-ngp's fixed step in a unit cube
    (its density is extinction per world unit, so per box unit it is scaled by the box side)."""
    from .radiance_field_render import MarchSettings

    side = float(snap.aabb[1, 0] - snap.aabb[0, 0])
    step = STEP_UNIT_CUBE / side
    return MarchSettings(tuple(float(v) for v in snap.aabb[0]), side, step, int(math.ceil(math.sqrt(3.0) / step)) + 1,
                         snap.background, side, GRID_SIZE)


def camera(snap: Snapshot, m) -> dict:
    """An orbit camera at the snapshot's camera position looking at the box centre (instant-ngp's own
    lens and roll are not carried over), or a default view of the box when it has none."""
    centre = [v + m.side / 2 for v in m.aabb_min]
    matrix = np.asarray(snap.camera.get("matrix", []), np.float64)
    eye = None
    if matrix.size == 12:   # mat4x3, column-major: the fourth column is the position
        eye = matrix.reshape(4, 3)[3]
    if eye is None or not np.all(np.isfinite(eye)) or np.linalg.norm(eye - centre) < 1e-6:
        eye = np.asarray(centre) + np.array([0.0, 0.3, 1.0]) * m.side * 1.6
    offset = eye - np.asarray(centre)
    distance = float(np.linalg.norm(offset))
    yaw = math.degrees(math.atan2(offset[0], offset[2]))
    pitch = -math.degrees(math.asin(max(-1.0, min(1.0, offset[1] / distance))))
    return {"type": "orbit", "fov_y": 50.0, "target": centre, "distance": distance, "yaw": yaw, "pitch": pitch}


def scene_dict(name: str, source_name: str, cam: dict) -> dict:
    """scene.json: the radiance field's pass on the two bundles, the torch march as the reference."""
    from inshade.scene.builder import (display_modes, network, reference, requires, scene_json, text_label,
                                        texture)

    from .radiance_field_render import PREFIX_FIELD, PREFIX_OCCUPANCY, PROGRAM, REFERENCE_UNIFORM, SETTINGS

    return scene_json(
        name, f"instant-ngp snapshot {source_name}", PROGRAM, (REFERENCE_SIZE, REFERENCE_SIZE),
        networks=[network(".", PREFIX_FIELD), network("occupancy", PREFIX_OCCUPANCY)],
        reference=reference(f"{REFERENCE_IMAGE}.exr", "linear", "screen"),
        textures=[texture(REFERENCE_UNIFORM, f"{REFERENCE_IMAGE}.png", mipmaps=False, repeat=False)],
        camera=cam, bookmarks={"snapshot": cam},
        display=display_modes("final", "reference", "error", "split"),
        labels=[text_label("torch march", (0.25, 0.95), {"view": "split"}),
                text_label("shader", (0.75, 0.95), {"view": "split"})],
        settings={k: dict(v) for k, v in SETTINGS.items()}, requires=requires(),
        notes="converted from an instant-ngp snapshot, which holds no ground truth: the reference is the torch "
              "march of this field at the scene's camera, so split and error show the shader against its twin",
    )


def convert(source, folder, *, force: bool = False, quiet: bool = False) -> str:
    """Write the asset: the field bundle (the folder), its occupancy grid (``occupancy/``), the torch
    march of the field at the scene's camera as the reference the split / error views compare the
    shader with (a snapshot holds no ground truth), and scene.json."""
    import json

    import torch

    from inshade import asset_folder
    from inshade.convert.lowering import ConvertError
    from inshade.files import atomic_write
    from inshade.scene.camera import camera_from_dict
    from inshade.scene.image_io import write_exr, write_png

    from . import radiance_field as rf
    from . import radiance_field_march as march
    from .image import save_fp16
    from .radiance_field_render import KIND

    folder = Path(folder)
    try:
        snap = read(source)
    except SnapshotError as exc:
        raise ConvertError(f"{source}: {exc}") from None
    asset_folder.claim(folder, folder.name, force=force, option="-o")
    graph = field_graph(snap)
    m = march_settings(snap)
    cells = torch.from_numpy(occupancy_bits(snap.density_grid, snap.aabb_scale))
    cam = camera(snap, m)
    uniforms = camera_from_dict(cam).uniforms(REFERENCE_SIZE, REFERENCE_SIZE)
    image, samples = march.render(march.graph_field(graph), cells, uniforms, REFERENCE_SIZE, REFERENCE_SIZE, m)
    provenance = {"source": "instant-ngp snapshot", "file": str(source), "params_dtype": snap.dtype,
                  "params_count": int(snap.params.size), "aabb_scale": snap.aabb_scale,
                  "activations": "density exp (clamped at 15), colour logistic: instant-ngp's defaults"}
    bundle = graph.export(KIND, folder.name, provenance=provenance, render=m.to_render(),
                          metrics={"occupied_fraction": round(float(cells.float().mean()), 4),
                                   "evaluations_per_pixel": round(float(np.mean(samples)), 2)})
    save_fp16(bundle, folder)
    rf.occupancy_bundle(cells, {"grid": f"instant-ngp's density bitfield, cascade {max_cascade(snap.aabb_scale)}"}) \
        .save(folder / "occupancy")
    write_exr(folder / f"{REFERENCE_IMAGE}.exr", image)
    write_png(folder / f"{REFERENCE_IMAGE}.png", image)
    atomic_write(folder / "scene.json", json.dumps(scene_dict(folder.name, Path(source).name, cam), indent=1) + "\n")
    return (f"wrote {folder}: instant-ngp NeRF, {snap.params.size} parameters ({snap.dtype}), "
            f"{100 * float(cells.float().mean()):.1f}% of the box occupied; reference = the torch march of the field")
