"""Sub-scene PRT (Learnt Transfer, Dhawal et al. 2022 §4.4): region split, δ-margin, variance merge, blend weights
(techniques/prt/regions.py), the region-selecting GLSL (lib/prt_regions.glsl through passes/sdf_prt.frag)
vs its torch twin (techniques/prt/region_twin.py), the seam, and named errors.

Parity rule (as tests/techniques/prt/test_prt.py): the blended transfer at the shader's own hit points and normals
(debug views 1..6) |glsl - torch| <= 1e-4; images PSNR >= 50 dB over a 48x48 render.
Seam: with two different networks meeting at x = 0, a hard switch (band 0) jumps by the networks'
difference there; the blend (band > 0) must make the jump between the two pixels straddling the
boundary no larger than the pixel-to-pixel change inside the band elsewhere (continuity), both read
back through the driver. Random untrained tiny networks: parity needs no training.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from inshade.techniques.prt import regions
from inshade.techniques.prt.region_twin import load_region_set, region_transfer, render_regions
from inshade.techniques.prt.transfer_model import TransferFrame, transfer_graph

from prt_gl import prt_settings, render_views

SIZE = 48
SDF_SCENE = {  # a floor slab with a few blobs across the grid's cell sides (occlusion on both sides)
    "format": "inshade.geometry.sdf", "version": 1, "name": "prt_regions_test",
    "bound": {"center": [0.0, 0.0, 0.0], "radius": 2.6},
    "trace": {"max_steps": 96, "step_scale": 0.9, "hit_eps": 0.001, "normal_eps": 0.001},
    "root": {"type": "union", "k": 0.1, "children": [
        {"type": "round_box", "size": [2.0, 0.1, 1.4], "radius": 0.03, "albedo": [0.6, 0.6, 0.65]},
        {"type": "transform", "translate": [0.1, 0.4, 0.3], "child": {"type": "sphere", "radius": 0.35},
         "albedo": [0.8, 0.5, 0.3]},
        {"type": "transform", "translate": [-1.0, 0.3, -0.5], "child": {"type": "sphere", "radius": 0.25}}]},
}
TOP = {"type": "orbit", "fov_y": 40.0, "target": [0.0, 0.0, 0.0], "distance": 5.2, "yaw": 0.0, "pitch": -89.0}
SLANT = {"type": "orbit", "fov_y": 40.0, "target": [0.0, 0.0, 0.0], "distance": 5.0, "yaw": -25.0, "pitch": -40.0}
SETTINGS = prt_settings("shading", "phong_exponent", "ks", "debug")
GRID = regions.RegionGrid(-2.0, -1.5, 2.0, 1.5, 2, 2)


def region_bundles(grid, table, band, seed=0, width=8):
    """Random tiny region networks, each in its own frame (a different output scale per network, so
    a wrong network or frame cannot pass)."""
    out = []
    for r in range(int(max(table)) + 1):
        torch.manual_seed(seed + 17 * r)
        g = transfer_graph(width=width, layers=1, pos_freqs=2, normal_freqs=1)
        frame = TransferFrame((0.5 * r - 0.5, 0.1, 0.25 * r), 1.5 + 0.25 * r, 1.0 + 0.2 * r)
        out.append(g.export("prt", f"region_{r}", render={
            "transfer": frame.to_dict(), "region": regions.region_record(grid, table, band, 0.3, r)}))
    return out


def write_regions(folder: Path, bundles, order, scene: dict) -> Path:
    """The region networks ``order`` (default: all, in turn) saved in ``folder`` beside a scene.json
    that lists them after the fields of ``scene`` (program, geometry, camera, environment)."""
    order = list(range(len(bundles))) if order is None else order
    for i in order:
        bundles[i].save(folder / f"region_{i}")
    data = {"format": "inshade.scene", "version": 1, "name": folder.name, "size": [SIZE, SIZE], **scene,
            "networks": [{"bundle": f"region_{i}", "prefix": f"reg{i}"} for i in order], "settings": SETTINGS}
    (folder / "scene.json").write_text(json.dumps(data))
    return folder


def write_region_scene(folder: Path, bundles, camera=TOP, order=None) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "sdf.json").write_text(json.dumps(SDF_SCENE))
    return write_regions(folder, bundles, order, {
        "program": "passes/sdf_prt.frag", "sdf": "sdf.json", "camera": camera,
        "environment": {"sky": "noon", "rotation": 0.0, "degree": 4}})



def _renders(folder, settings_seq, program_cache, size=SIZE):
    views, sh, scene, bundles = render_views(program_cache, folder, settings_seq, size)
    return [image for image, in views], sh, scene, bundles


def _gl_transfer(folder, program_cache, size=SIZE):
    """(positions [H, W, 4], normals, transfer [H, W, 16]) the shader computed (debug views)."""
    images, _, _, bundles = _renders(folder, [{"debug": d} for d in (5, 6, 1, 2, 3, 4)], program_cache, size)
    return images[0], images[1], np.concatenate(images[2:], -1), bundles


# GLSL vs torch ---------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def three_regions(tmp_path_factory):
    table = np.array([0, 1, 2, 2])        # four cells, three networks: sides between 0|1, 0|2, 1|2, a corner
    bundles = region_bundles(GRID, table, (0.15, 0.2))
    # the scene lists the networks out of order: the region index, not the list position, selects
    return write_region_scene(tmp_path_factory.mktemp("three_regions"), bundles, SLANT, order=[2, 0, 1])


def check_region_transfer(pos, nrm, t_gl, bundles, mask):
    """The shader's blended transfer ``t_gl`` at the ``mask``ed points (positions ``pos``, normals
    ``nrm``) against the torch twin: |glsl - torch| <= 1e-4, and the view holds blended pixels and
    corner pixels. Returns torch's transfer there and each point's network ids (blend order)."""
    rs, nets, frames = load_region_set(bundles)
    p = torch.from_numpy(pos[mask][:, :3])
    ref = region_transfer(rs, nets, frames, p, torch.from_numpy(nrm[mask][:, :3])).numpy()
    err = np.abs(t_gl[mask] - ref).max()
    assert err <= 1e-4, f"max |glsl - torch| {err:.3g}"
    ids, w = regions.blend_weights(rs.grid, np.asarray(rs.table), rs.band, p.numpy())
    assert ((w > 0).sum(1) >= 2).sum() > 20 and ((w > 0).sum(1) >= 3).any()
    return ref, ids


def test_region_transfer_glsl_vs_torch_at_hit_points(program_cache, three_regions):
    pos, nrm, t_gl, bundles = _gl_transfer(three_regions, program_cache)
    mask = pos[..., 3] > 0.5
    assert mask.mean() > 0.3
    _, ids = check_region_transfer(pos, nrm, t_gl, bundles, mask)
    assert set(ids[:, 0].tolist()) >= {0, 1, 2}      # the view covers every network


@pytest.mark.parametrize("mode", ["diffuse", "glossy"])
def test_region_image_glsl_vs_torch(program_cache, three_regions, mode):
    images, sh, scene, bundles = _renders(three_regions, [{"shading": mode, "ks": 0.7}], program_cache)
    rs, nets, frames = load_region_set(bundles)
    from inshade.techniques.prt.twin import PrtShading

    cam = scene.make_camera()
    ref = render_regions(scene.sdf, rs, nets, frames, cam.uniforms(SIZE, SIZE), SIZE, SIZE, sh,
                         PrtShading(mode=mode, exponent=8.0, ks=0.7))
    assert ref["hit"].mean() > 0.3
    assert np.abs(ref["rgba"][..., :3][ref["hit"]]).max() > 0.05
    err = np.mean((np.clip(images[0][..., :3], 0, 1) - np.clip(ref["rgba"][..., :3], 0, 1)) ** 2)
    psnr = 99.0 if err == 0 else 10 * math.log10(1.0 / err)
    assert psnr >= 50.0, f"{mode}: PSNR {psnr:.1f} dB"


# the seam -----------------------------------------------------------------------------------------------
def seam_rows(pos, nrm, t_gl, bundles, surface, boundary_pair):
    """Per pixel row of a top view crossing x = 0: the |T| jump between the two ``surface`` pixels
    straddling it (``boundary_pair(left, right)``: their indices, or None to skip the row), the
    largest pixel-to-pixel change within the band away from that pair, and the shader/twin
    difference over the band pixels on both sides. ``surface(row)``: the row's flat-surface mask."""
    rs, nets, frames = load_region_set(bundles)
    jumps, inner, parity = [], [], []
    for row in range(pos.shape[0]):
        x, flat = pos[row, :, 0], surface(row)
        left, right = np.nonzero(flat & (x < 0))[0], np.nonzero(flat & (x >= 0))[0]
        pair = boundary_pair(left, right) if len(left) and len(right) else None
        if pair is None:
            continue
        a, b = pair
        jumps.append(np.abs(t_gl[row, a] - t_gl[row, b]).max())
        band = np.nonzero(flat & (np.abs(x) < 0.3))[0]
        steps = [np.abs(t_gl[row, i + 1] - t_gl[row, i]).max() for i in band[:-1]
                 if i + 1 in band and {i, i + 1} != {a, b}]
        inner.append(max(steps) if steps else 0.0)
        sel = flat & (np.abs(x) < 0.3)
        ref = region_transfer(rs, nets, frames, torch.from_numpy(pos[row, sel, :3]),
                              torch.from_numpy(nrm[row, sel, :3])).numpy()
        parity.append(np.abs(t_gl[row, sel] - ref).max())
    assert len(jumps) >= 10, "the top view should cross the boundary on many rows"
    return np.array(jumps), np.array(inner), np.array(parity)


def check_seam(write_scene, row_jumps, program_cache, tmp_path):
    """Two networks side by side: blended across the seam the picture is continuous, switched hard
    it jumps, and on both sides the shader agrees with the twin."""
    grid = regions.RegionGrid(-2.0, -1.5, 2.0, 1.5, 2, 1)
    table = np.array([0, 1])
    blended = write_scene(tmp_path / "blend", region_bundles(grid, table, (0.1, 0.0), seed=3), TOP)
    hard = write_scene(tmp_path / "hard", region_bundles(grid, table, (0.0, 0.0), seed=3), TOP)
    j_blend, inner, parity = row_jumps(blended, program_cache)
    j_hard, _, parity_hard = row_jumps(hard, program_cache)
    # both sides of the band agree with the twin
    assert parity.max() <= 1e-4 and parity_hard.max() <= 1e-4, (parity.max(), parity_hard.max())
    # the hard switch jumps by the networks' difference (the test can fail) ...
    assert np.median(j_hard) > 0.02, j_hard
    # ... the blend is continuous: the step across x = 0 is like any step inside the band
    assert np.all(j_blend <= 2.0 * inner + 1e-4), (j_blend, inner)
    assert np.median(j_blend) < 0.25 * np.median(j_hard)


def _adjacent(left, right):
    """The pair straddling x = 0 where the row's surface pixels run on across it."""
    if right[0] == left[-1] + 1:
        return left[-1], right[0]
    return (right[-1], left[0]) if left[0] == right[-1] + 1 else None


def _row_jumps(folder, program_cache):
    """seam_rows over a top view of the slab."""
    pos, nrm, t_gl, bundles = _gl_transfer(folder, program_cache, 64)
    return seam_rows(pos, nrm, t_gl, bundles, lambda row: (pos[row, :, 3] > 0.5)
                     & (np.abs(nrm[row, :, 1] - 1.0) < 1e-3) & (np.abs(pos[row, :, 2]) < 1.2), _adjacent)


def test_seam_blend_is_continuous_and_hard_switch_is_not(program_cache, tmp_path):
    check_seam(write_region_scene, _row_jumps, program_cache, tmp_path)


def test_blend_is_continuous_in_the_twin_along_a_fine_line():
    """The twin's weights per network (hence the transfer) change by O(step) across every side."""
    table = np.array([0, 1, 2, 2])
    band = (0.15, 0.2)
    x = np.linspace(-0.05, 0.05, 2001)
    for z in (-0.75, 0.0, 0.02, 0.75):
        p = np.stack([x, np.full_like(x, 0.1), np.full_like(x, z)], -1).astype(np.float32)
        w = _per_network(GRID, table, band, p)
        assert np.abs(np.diff(w, axis=0)).max() < 0.01
    hard = _per_network(GRID, table, (0.0, 0.0), np.array([[-1e-4, 0, -0.5], [1e-4, 0, -0.5]], np.float32))
    assert np.abs(hard[1] - hard[0]).max() == 1.0


def _per_network(grid, table, band, p):
    ids, w = regions.blend_weights(grid, table, band, p)
    n = int(table.max()) + 1
    return np.stack([np.where(ids == r, w, 0).sum(1) for r in range(n)], -1)


# unit properties ---------------------------------------------------------------------------------------
grids = st.builds(lambda nx, nz, w, d: regions.RegionGrid(-w, -d, w, d, nx, nz), st.integers(1, 5),
                  st.integers(1, 4), st.floats(0.5, 10), st.floats(0.5, 10))


@settings(max_examples=25, deadline=None)
@given(grid=grids, seed=st.integers(0, 2 ** 16), band=st.one_of(st.just(0.0), st.floats(1e-3, 0.5)),
       nets=st.integers(1, 6))
def test_blend_weights_partition_unity(grid, seed, band, nets):
    rng = np.random.default_rng(seed)
    table = np.arange(grid.cells) % min(nets, grid.cells)
    p = rng.uniform(-12, 12, (200, 3)).astype(np.float32)
    ids, w = regions.blend_weights(grid, table, band, p)
    assert (w >= 0).all()
    np.testing.assert_allclose(w.sum(1), 1.0, atol=1e-6)
    own = table[grid.cell_of(p)]
    # the own cell's network always takes at least a quarter (1/2 per axis), and is in slot 0
    assert (ids[:, 0] == own).all() and (w[:, 0] >= 0.25 - 1e-6).all()
    named = ids[w > 0]
    assert set(named.tolist()) <= set(table.tolist())
    # a network named once per point (duplicates folded)
    for row_ids, row_w in zip(ids, w):
        used = row_ids[row_w > 0]
        assert len(used) == len(set(used.tolist()))


@settings(max_examples=25, deadline=None)
@given(grid=grids, seed=st.integers(0, 2 ** 16), delta=st.floats(0.0, 3.0))
def test_margin_contains_the_cells_and_grows_with_delta(grid, seed, delta):
    rng = np.random.default_rng(seed)
    p = rng.uniform(-12, 12, (300, 3)).astype(np.float32)
    cells = sorted(set(rng.integers(0, grid.cells, 2).tolist()))
    inside = np.isin(grid.cell_of(p), cells)
    m0 = regions.margin_mask(grid, cells, p, 0.0)
    m = regions.margin_mask(grid, cells, p, delta)
    m2 = regions.margin_mask(grid, cells, p, delta + 1.0)
    assert (m0 >= inside).all() and (m >= m0).all() and (m2 >= m).all()
    # points in the margin are within delta (xz) of a point of the cells' rectangles
    extra = m & ~m0
    for q in p[extra][:20]:
        d = min(_rect_distance(grid.rect(c), q) for c in cells)
        assert d <= delta + 1e-5


def _rect_distance(rect, q):
    x0, z0, x1, z1 = rect
    dx = max(x0 - q[0], q[0] - x1, 0.0)
    dz = max(z0 - q[2], q[2] - z1, 0.0)
    return math.hypot(dx, dz)


@settings(max_examples=25, deadline=None)
@given(grid=grids, seed=st.integers(0, 2 ** 16), target=st.integers(1, 20))
def test_merge_partitions_into_connected_regions(grid, seed, target):
    rng = np.random.default_rng(seed)
    p = rng.uniform(-12, 12, (400, 3)).astype(np.float32)
    t = rng.normal(size=(400, 16)) * (1 + (p[:, :1] > 0))      # one half of the plan varies more
    target = min(target, grid.cells)
    table = regions.merge_regions(grid, grid.cell_of(p), t, max_networks=target)
    n = int(table.max()) + 1
    assert n == target and sorted(set(table.tolist())) == list(range(n))
    for r in range(n):                      # each network's cells are 4-connected
        cells = set(np.nonzero(table == r)[0].tolist())
        seen, todo = set(), [min(cells)]
        while todo:
            c = todo.pop()
            if c in seen:
                continue
            seen.add(c)
            todo += [d for d in grid.neighbours(c) if d in cells]
        assert seen == cells
    # networks are numbered by their first cell
    firsts = [int(np.nonzero(table == r)[0][0]) for r in range(n)]
    assert firsts == sorted(firsts)


def test_merge_joins_the_low_variance_cells_first():
    grid = regions.RegionGrid(0.0, 0.0, 4.0, 1.0, 4, 1)
    rng = np.random.default_rng(0)
    cells = np.repeat(np.arange(4), 100)
    t = rng.normal(size=(400, 16)) * np.array([5.0, 0.01, 0.01, 5.0])[cells, None]   # two quiet middle cells
    t[cells == 0] += 10.0
    t[cells == 3] -= 10.0
    assert regions.merge_regions(grid, cells, t, max_networks=3).tolist() == [0, 1, 1, 2]
    # a variance bound alone: only the quiet pair is cheap enough
    assert regions.merge_regions(grid, cells, t, max_variance=0.01).tolist() == [0, 1, 1, 2]
    assert regions.merge_regions(grid, cells, t, max_variance=0.0).tolist() == [0, 1, 2, 3]


# errors ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("args,field", [((0, 0, 1, 1, 0, 1), "grid.nx"), ((0, 0, 0, 1, 1, 1), "grid: needs x1 > x0"),
                                        ((0, 0, float("nan"), 1, 1, 1), "grid.x1")])
def test_bad_grid_names_the_field(args, field):
    with pytest.raises(regions.RegionError, match=field.replace(".", r"\.")):
        regions.RegionGrid(*args)


def test_bad_inputs_name_the_field():
    with pytest.raises(regions.RegionError, match="table"):
        regions.blend_weights(GRID, [0, 1, 3, 3], 0.1, np.zeros((1, 3)))
    for band in (0.7, 1e-9, -0.1):
        with pytest.raises(regions.RegionError, match="band"):
            regions.blend_weights(GRID, [0, 0, 0, 0], band, np.zeros((1, 3)))
    with pytest.raises(regions.RegionError, match="points"):
        regions.blend_weights(GRID, [0, 0, 0, 0], 0.1, np.full((1, 3), np.nan))
    with pytest.raises(regions.RegionError, match="delta"):
        regions.margin_mask(GRID, [0], np.zeros((1, 3)), -1.0)
    with pytest.raises(regions.RegionError, match="max_networks and/or max_variance"):
        regions.merge_regions(GRID, np.zeros(4, int), np.zeros((4, 16)))
    with pytest.raises(regions.RegionError, match="transfer"):
        regions.merge_regions(GRID, np.zeros(4, int), np.zeros((3, 16)), max_networks=2)


def test_inconsistent_region_sets_fail_with_the_field(tmp_path):
    from inshade.runtime.context import shared_context
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import load_scene

    table = np.array([0, 1, 2, 2])
    bundles = region_bundles(GRID, table, 0.1)
    other = region_bundles(GRID, np.array([0, 1, 1, 2]), 0.1)
    with pytest.raises(regions.RegionError, match=r"render\.region\.table: differs"):
        regions.read_region_set([bundles[0], other[1], bundles[2]])
    with pytest.raises(regions.RegionError, match=r"networks: the table names networks 0\.\.2"):
        regions.read_region_set(bundles[:2])
    with pytest.raises(regions.RegionError, match=r"render\.region\.index: must be a unique int"):
        regions.read_region_set([bundles[0], bundles[0], bundles[2]])
    # through the scene: one network of the set missing -> one error naming "networks"
    folder = write_region_scene(tmp_path / "missing", bundles, order=[0, 1])
    with pytest.raises(ValueError, match=r"networks: .*table names networks 0\.\.2"):
        SceneRenderer(load_scene(folder), shared_context())


def test_region_chunk_declares_each_network_once():
    table = np.array([0, 1, 2, 2])
    bundles = region_bundles(GRID, table, 0.1)
    from inshade.techniques.prt.codegen import transfer_frame

    chunk = regions.region_chunks(bundles, [f"reg{i}" for i in range(3)], [transfer_frame(b) for b in bundles])
    text = chunk["prt_network"]
    for i in range(3):
        assert text.count(f"reg{i}_eval") == 1 and f"#include <network_reg{i}>" in text
    assert "const int PRT_REGION_TABLE[4] = int[](0, 1, 2, 2);" in text


# the asset builder's recipe ---------------------------------------------------------------------------
def test_builder_presets_and_the_baseline_width():
    from inshade.techniques.prt import regions_train
    from inshade.techniques.prt.transfer_model import transfer_graph

    with pytest.raises(SystemExit) as exit_:
        regions_train.main(["--help"])
    assert exit_.value.code == 0
    with pytest.raises(ValueError, match="--preset"):
        regions_train.preset_settings("huge")
    ship = regions_train.preset_settings("ship")
    assert ship["grid"] == (4, 3) and ship["networks"] <= 12
    # the one-network baseline with the set's parameter count: nearest width (multiple of 4)
    def params(k):
        return sum(p.numel() for p in transfer_graph(width=k, layers=4).parameters())
    target = 9 * params(16)
    k = regions_train.width_for_params(target, 4)
    assert k % 4 == 0 and all(abs(params(k) - target) <= abs(params(j) - target) for j in (k - 4, k + 4))


def test_atrium_scene_is_large_and_valid():
    from inshade.geometry.sdf import parse_sdf
    from inshade.techniques.prt.atrium import BOUND_RADIUS, atrium

    scene = parse_sdf(atrium())
    creature = json.loads((Path(__file__).resolve().parents[3] / "trained/prt_creature/sdf.json").read_text())
    assert scene.radius >= 4 * creature["bound"]["radius"] and scene.radius == BOUND_RADIUS
    with pytest.raises(ValueError, match="scale"):
        atrium(0.0)


def test_shipped_atrium_records_its_ship_preset_and_a_consistent_region_set():
    from inshade.bundle import load
    from inshade.scene.description import load_scene
    from inshade.techniques.prt import regions_train

    root = Path(__file__).resolve().parents[3] / "trained" / "prt_atrium"
    m = json.loads((root / "metrics.json").read_text())
    assert m["preset"] == "ship"
    assert m["settings"] == json.loads(json.dumps(regions_train.preset_settings("ship")))
    q = m["quality"]
    assert (q["n_views"], q["size"], q["n_dirs"]) == (m["settings"]["quality_views"], m["settings"]["quality_size"],
                                                       m["settings"]["quality_dirs"])
    scene = load_scene(root)
    rs = regions.read_region_set([load(n.bundle) for n in scene.networks])
    assert rs.count == m["regions"]["networks"] <= m["settings"]["networks"]
    assert list(rs.table) == m["regions"]["table"]
