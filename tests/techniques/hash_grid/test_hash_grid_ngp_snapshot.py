"""instant-ngp NeRF snapshots (techniques/hash_grid/ngp_snapshot.py): snapshots written here to the
layout instant-ngp's source establishes (no real one can be made without CUDA). The network is
checked against tiny-cuda-nn's forward reimplemented from its source (tests/tcnn_reference.py)
composed as instant-ngp's NerfNetwork composes it; the occupancy grid against Morton codes written
independently here."""
from __future__ import annotations

import zlib

import msgpack
import numpy as np
import pytest
import torch

import tcnn_reference as ref
from inshade.convert.lowering import ConvertError
from inshade.techniques.hash_grid import ngp_snapshot as ns

POS = {"otype": "HashGrid", "n_levels": 4, "n_features_per_level": 2, "log2_hashmap_size": 12,
       "base_resolution": 8, "per_level_scale": 1.5}
CONFIG = {"encoding": POS,
          "network": {"otype": "FullyFusedMLP", "activation": "ReLU", "output_activation": "None",
                      "n_neurons": 16, "n_hidden_layers": 1},
          "dir_encoding": {"otype": "Composite", "nested": [
              {"n_dims_to_encode": 3, "otype": "SphericalHarmonics", "degree": 4}, {"otype": "Identity"}]},
          "rgb_network": {"otype": "FullyFusedMLP", "activation": "ReLU", "output_activation": "None",
                          "n_neurons": 16, "n_hidden_layers": 2}}
DENSITY = {"n_input_dims": 3, "n_output_dims": 16, "encoding": POS, "network": CONFIG["network"]}
DIRECTION = {"n_input_dims": 3, "encoding": CONFIG["dir_encoding"]}


def rgb_model():
    return {"n_input_dims": 16 + ref.build(DIRECTION)["n_out"], "n_output_dims": 3, "network": CONFIG["rgb_network"]}


def counts():
    """(density network, rgb network, position encoding, direction encoding): NerfNetwork's order."""
    dens = ref.build(DENSITY)
    return (dens["n_params"] - dens["encoding"]["n_params"], ref.build(rgb_model())["n_params"],
            dens["encoding"]["n_params"], ref.build(DIRECTION)["n_params"])


def morton3d(x, y, z) -> int:
    """Bit b of axis a -> bit 3b + a (tiny-cuda-nn common_device.h morton3D), written bit by bit."""
    code = 0
    for b in range(7):
        code |= ((x >> b) & 1) << (3 * b) | ((y >> b) & 1) << (3 * b + 1) | ((z >> b) & 1) << (3 * b + 2)
    return code


def write_snapshot(path, params: np.ndarray, *, grid=None, aabb_scale: int = 1, config=CONFIG, compress=False,
                   **snapshot_fields):
    cascades = ns.max_cascade(aabb_scale) + 1
    grid = np.zeros(cascades * 128 ** 3, np.float16) if grid is None else grid
    half = aabb_scale / 2
    snap = {"version": 1, "mode": "Nerf", "params_type": "__half" if params.dtype == np.float16 else "float",
            "n_params": int(params.size), "params_binary": params.tobytes(), "density_grid_size": 128,
            "density_grid_binary": grid.astype(np.float16).tobytes(), "nerf": {"aabb_scale": aabb_scale},
            "aabb": {"min": [0.5 - half] * 3, "max": [0.5 + half] * 3}, "background_color": [0.1, 0.2, 0.3, 1.0]}
    snap.update(snapshot_fields)
    raw = msgpack.packb({**config, "snapshot": snap}, use_bin_type=True)
    path.write_bytes(zlib.compress(raw) if compress else raw)
    return path


def random_params(seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    n = counts()
    return np.concatenate([rng.normal(0, 0.3, n[0]), rng.normal(0, 0.3, n[1]), rng.uniform(-1, 1, n[2]),
                           rng.normal(0, 0.1, n[3])]).astype(np.float16)


def nerf_reference(params: np.ndarray, x: np.ndarray, d: np.ndarray) -> np.ndarray:
    """instant-ngp's NerfNetwork: density net on the position encoding, rgb net on [its 16 lanes,
    the direction encoding of (d + 1) / 2]; density = exp(lane 0), colour = logistic."""
    p = params.astype(np.float32)
    n_dnet, n_rgb, n_pos, _ = counts()
    density_params = np.concatenate([p[:n_dnet], p[n_dnet + n_rgb:n_dnet + n_rgb + n_pos]])
    geo = ref.forward(DENSITY, density_params, x, dtype="float16")
    dirs = ref.forward(DIRECTION, p[n_dnet + n_rgb + n_pos:], (d + 1) / 2)
    rgb = ref.forward(rgb_model(), p[n_dnet:n_dnet + n_rgb], np.concatenate([geo, dirs], 1), dtype="float16")
    return np.concatenate([np.exp(np.minimum(geo[:, :1], 15.0)), 1 / (1 + np.exp(-rgb))], 1)


@pytest.mark.parametrize("compress", [False, True])
def test_network_matches_instant_ngp(tmp_path, compress):
    params = random_params()
    path = write_snapshot(tmp_path / ("s.ingp" if compress else "s.msgpack"), params, compress=compress)
    snap = ns.read(path)
    assert snap.dtype == "float16" and snap.params.size == params.size
    graph = ns.field_graph(snap)
    rng = np.random.default_rng(1)
    x = rng.uniform(0, 1, (512, 3)).astype(np.float32)
    d = rng.normal(size=(512, 3))
    d = (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)
    with torch.no_grad():
        got = graph(torch.from_numpy(np.concatenate([x, d], 1))).numpy()
    want = nerf_reference(params, x, d)
    # the grid's position is rounded twice here, fused there (one ulp of it, docs/tcnn.md), and the
    # direction goes through (d + 1) / 2 * 2 - 1: a few ulp through two small networks
    err = np.abs(got - want) / np.maximum(1.0, np.abs(want))
    assert err.max() < 1e-5, err.max()
    assert want[:, 0].std() > 0.1 and want[:, 1:].std() > 0.05    # the check sees a varied field


def test_occupancy_follows_morton_order_and_cascades():
    n = 128 ** 3
    grid = np.zeros(2 * n, np.float32)
    grid[:n] = 0.001                       # mean 0.001: threshold min(0.01, mean)
    cells = [(0, 0, 0), (5, 17, 99), (127, 64, 3)]
    for x, y, z in cells:
        grid[morton3d(x, y, z)] = 1.0
    grid[n + morton3d(1, 2, 3)] = 1.0       # a cell of cascade 1 only, outside cascade 0's region
    bits = ns.occupancy_bits(grid, 2)       # aabb_scale 2: cascade 1 is the box
    want = np.zeros((128,) * 3, bool)
    for x, y, z in cells:                   # cascade 0 covers the central half of cascade 1
        want[32 + z // 2, 32 + y // 2, 32 + x // 2] = True
    want[3, 2, 1] = True
    assert np.array_equal(bits, want)
    one = ns.occupancy_bits(grid[:n], 1)
    assert {tuple(c) for c in np.argwhere(one)} == {(z, y, x) for x, y, z in cells}


@pytest.mark.parametrize("field, change, message", [
    ("n_params", lambda s: s.update(n_params=5), "snapshot.n_params: 5, but params_binary holds"),
    ("mode", lambda s: s.update(mode="Sdf"), "snapshot.mode: 'Sdf'; only NeRF snapshots"),
    ("version", lambda s: s.update(version=0), "snapshot.version: 0"),
    ("aabb_scale", lambda s: s["nerf"].update(aabb_scale=3), "snapshot.nerf.aabb_scale: 3"),
    ("grid", lambda s: s.update(density_grid_binary=b"\0\0" * 10), "snapshot.density_grid_binary: 10 cells"),
    ("params_type", lambda s: s.update(params_type="double"), "snapshot.params_type: 'double'"),
])
def test_bad_snapshots_name_the_field(tmp_path, field, change, message):
    path = write_snapshot(tmp_path / "s.msgpack", random_params())
    doc = msgpack.unpackb(path.read_bytes(), raw=False)
    change(doc["snapshot"])
    path.write_bytes(msgpack.packb(doc, use_bin_type=True))
    with pytest.raises(ns.SnapshotError, match=message.replace("(", r"\(")):
        ns.read(path)


def test_wrong_parameter_count_names_each_part(tmp_path):
    params = random_params()[:-8]
    snap = ns.read(write_snapshot(tmp_path / "s.msgpack", params))
    n = counts()
    with pytest.raises(ConvertError, match=rf"the config needs {sum(n)} \(density network {n[0]}, rgb network {n[1]}"):
        ns.field_graph(snap)


def blob_grid() -> np.ndarray:
    """A density grid occupied in a ball around the box centre (cascade 0 of aabb_scale 1)."""
    idx = np.arange(128 ** 3)
    xyz = ns.morton_decode(idx)
    inside = np.linalg.norm((xyz + 0.5) / 128 - 0.5, axis=1) < 0.3
    return np.where(inside, 1.0, 0.0).astype(np.float16)


def test_convert_writes_an_asset_render_draws(tmp_path):
    """inshade convert snapshot -o folder, then inshade render: the shader's march of the converted field
    matches its torch march (the asset's reference) at the scene's camera, and a second convert into
    the folder is refused without --force."""
    import subprocess
    import sys

    from PIL import Image

    from inshade.metrics import psnr

    snap = write_snapshot(tmp_path / "s.ingp", random_params(), grid=blob_grid(), compress=True)
    out = tmp_path / "asset"
    run = lambda *a: subprocess.run([sys.executable, "-m", "inshade.cli", *a], capture_output=True, text=True)  # noqa: E731
    r = run("convert", str(snap), "-o", str(out))
    assert r.returncode == 0, r.stderr
    assert (out / "occupancy" / "bundle.json").is_file() and (out / "scene.json").is_file()
    again = run("convert", str(snap), "-o", str(out))
    assert again.returncode == 2 and again.stderr.startswith("inshade: error: ")
    r = run("render", str(out), "-o", str(tmp_path / "frame.png"))
    assert r.returncode == 0, r.stderr
    frame = np.asarray(Image.open(tmp_path / "frame.png").convert("RGB"), np.float32) / 255
    twin = np.asarray(Image.open(out / f"{ns.REFERENCE_IMAGE}.png").convert("RGB"), np.float32) / 255
    assert frame.shape == twin.shape == (ns.REFERENCE_SIZE, ns.REFERENCE_SIZE, 3)
    assert twin.std() > 0.02                     # the blob is drawn, not only background
    assert psnr(frame, twin) > 40.0              # 8-bit sRGB of the same march, GL and torch


def test_convert_refuses_other_network_options(tmp_path):
    import subprocess
    import sys

    snap = write_snapshot(tmp_path / "s.msgpack", random_params())
    r = subprocess.run([sys.executable, "-m", "inshade.cli", "convert", str(snap), "-o", str(tmp_path / "a"),
                        "--as", "image"], capture_output=True, text=True)
    assert r.returncode == 2 and "--as does not apply to a .msgpack file" in r.stderr
