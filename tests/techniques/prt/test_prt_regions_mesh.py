"""Sub-scene PRT on triangle meshes (Learnt Transfer, Dhawal et al. 2022 §4.4, "select the network by region"):
a region set rendered by the deferred passes/mesh_prt.frag (a G-buffer of position + normal, then one
full-screen pass whose generated prt_transfer selects the network by the region of the G-buffer's
surface point, techniques/prt/regions.py + lib/prt_regions.glsl) vs its torch twin fed the same
G-buffer (techniques/prt/region_twin.py render_gbuffer_regions).

Rules as tests/techniques/prt/test_prt_regions.py and tests/techniques/prt/test_prt.py's mesh tests: the blended transfer at the
G-buffer points (debug views 1..4) |glsl - torch| <= 1e-4; images PSNR >= 50 dB over a 48x48 render.
Seam: across a cell side crossing the floor, the hard switch (band 0) jumps by the two networks'
difference, the blend (band > 0) is no larger than the pixel-to-pixel change inside the band.
Per draw: a mesh part lying in one cell away from the band is shaded by that cell's network alone,
which is what selecting the network per draw would give it. Random untrained tiny networks.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import torch

from inshade.techniques.prt import regions
from inshade.techniques.prt.region_twin import load_region_set, render_gbuffer_regions
from inshade.techniques.prt.transfer_model import evaluate_transfer
from inshade.techniques.prt.twin import PrtShading

from prt_gl import render_views
from test_prt_regions import SLANT, check_region_transfer, check_seam, region_bundles, seam_rows, write_regions

SIZE = 48
GRID = regions.RegionGrid(-2.0, -1.5, 2.0, 1.5, 2, 2)
# the parts: a floor (a flat grid: exact up normals), a box wholly inside cell 0 (away from every
# band) and a box straddling the cell side x = 0 (occluder and blended surface on both sides)
BOX_INSIDE = ((-1.45, 0.0, -1.0), (-0.95, 0.5, -0.45))     # (min, max)
BOX_ACROSS = ((-0.2, 0.0, 0.35), (0.3, 0.4, 0.85))


def floor_mesh(nx=16, nz=12, x=(-2.0, 2.0), z=(-1.5, 1.5)):
    import trimesh

    xs, zs = np.linspace(*x, nx + 1), np.linspace(*z, nz + 1)
    gx, gz = np.meshgrid(xs, zs, indexing="xy")
    v = np.stack([gx.ravel(), np.zeros(gx.size), gz.ravel()], -1)
    i = np.arange((nz + 1) * (nx + 1)).reshape(nz + 1, nx + 1)
    a, b, c, d = i[:-1, :-1].ravel(), i[:-1, 1:].ravel(), i[1:, :-1].ravel(), i[1:, 1:].ravel()
    faces = np.concatenate([np.stack([a, c, b], -1), np.stack([b, c, d], -1)])   # counter-clockwise from +y
    return trimesh.Trimesh(v, faces, process=False)


def box_mesh(lo, hi):
    import trimesh.creation

    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    box = trimesh.creation.box(extents=hi - lo)
    box.apply_translation((lo + hi) / 2 + [0.0, 1e-3, 0.0])   # just above the floor: no welded normals
    return box


def parts_mesh():
    import trimesh

    parts = [floor_mesh(), box_mesh(*BOX_INSIDE), box_mesh(*BOX_ACROSS)]
    return trimesh.util.concatenate(parts), [len(p.faces) for p in parts]


def write_mesh_scene(folder: Path, bundles, camera, order=None) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    mesh, _ = parts_mesh()
    mesh.export(folder / "mesh.ply")
    return write_regions(folder, bundles, order, {
        "program": "passes/mesh_prt.frag", "mesh": "mesh.ply", "camera": camera,
        "environment": {"sky": "sunset", "rotation": 30.0, "degree": 4}})



def _renders(folder, settings_seq, program_cache, size=SIZE):
    """GL images (image orientation) per settings dict, the G-buffer position/normal of the last
    (data orientation), the environment SH, the scene and the bundles."""
    views, sh, scene, bundles = render_views(program_cache, folder, settings_seq, size, targets=2)
    _, pos, nrm = views[-1]
    return [image for image, _, _ in views], pos, nrm, sh, scene, bundles


def _gl_transfer(folder, program_cache, size=SIZE):
    """(G-buffer position [H, W, 4], normal, transfer [H, W, 16] the pass computed, bundles), all in
    data orientation (row 0 = GL y 0)."""
    images, pos, nrm, _, _, bundles = _renders(folder, [{"debug": d} for d in (1, 2, 3, 4)], program_cache, size)
    return pos, nrm, np.concatenate([img[::-1] for img in images], -1), bundles


# GLSL vs torch ---------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def three_regions(tmp_path_factory, program_cache):
    table = np.array([0, 1, 2, 2])        # sides 0|1, 0|2, 1|2 and a corner cross the floor
    bundles = region_bundles(GRID, table, (0.15, 0.2), seed=7)
    folder = write_mesh_scene(tmp_path_factory.mktemp("mesh_three_regions"), bundles, SLANT, order=[1, 2, 0])
    return folder, _gl_transfer(folder, program_cache)


def test_mesh_scene_has_parts_over_several_cells():
    mesh, counts = parts_mesh()
    assert 300 <= len(mesh.faces) <= 1000 and counts[0] == 384
    cells = set(GRID.cell_of(np.asarray(mesh.vertices, np.float32)).tolist())
    assert cells == {0, 1, 2, 3}
    # the inside box lies in cell 0, beyond the blend band of every side (band <= 0.2 cell)
    lo, hi = np.array(BOX_INSIDE)
    c = GRID.coords(np.array([lo, hi], np.float32))
    assert (GRID.cell_of(np.array([lo, hi], np.float32)) == 0).all() and c.min() > 0.2 and c.max() < 0.8


def test_mesh_region_transfer_glsl_vs_torch_at_gbuffer_points(three_regions):
    _, (pos, nrm, t_gl, bundles) = three_regions
    covered = pos[..., 3] > 0
    assert covered.mean() > 0.3
    ref, ids = check_region_transfer(pos, nrm, t_gl, bundles, covered)
    assert np.abs(ref).max() > 0.05
    assert set(ids[:, 0].tolist()) == {0, 1, 2}      # the view covers every network


def test_mesh_part_in_one_cell_is_shaded_by_that_cells_network_alone(three_regions):
    """"Per draw" in the deferred pass: every G-buffer point of the box inside cell 0 gets network 0
    in its own frame (what drawing that part with network 0 would give); another network would not."""
    _, (pos, nrm, t_gl, bundles) = three_regions
    lo, hi = np.array(BOX_INSIDE)
    p = pos[..., :3]
    part = (pos[..., 3] > 0) & np.all((p > lo - 1e-3) & (p < hi + 2e-3), -1) & (p[..., 1] > 0.01)
    assert part.sum() >= 10
    rs, nets, frames = load_region_set(bundles)
    pp, nn = torch.from_numpy(p[part]), torch.from_numpy(nrm[part][:, :3])
    with torch.no_grad():
        own = evaluate_transfer(nets[0], frames[0], pp, nn).float().numpy()
        other = evaluate_transfer(nets[1], frames[1], pp, nn).float().numpy()
    assert np.abs(t_gl[part] - own).max() <= 1e-4
    assert np.abs(t_gl[part] - other).max() > 0.02


@pytest.mark.parametrize("mode", ["diffuse", "glossy"])
def test_mesh_region_image_glsl_vs_torch(program_cache, three_regions, mode):
    folder, _ = three_regions
    images, pos, nrm, sh, scene, bundles = _renders(folder, [{"shading": mode, "ks": 0.7}], program_cache)
    rs, nets, frames = load_region_set(bundles)
    ref = render_gbuffer_regions(pos, nrm, rs, nets, frames, scene.make_camera().uniforms(SIZE, SIZE), SIZE, SIZE,
                                 sh, PrtShading(mode=mode, exponent=8.0, ks=0.7))
    assert ref["hit"].mean() > 0.3
    assert np.abs(ref["rgba"][..., :3][ref["hit"]]).max() > 0.05
    err = np.mean((np.clip(images[0][..., :3], 0, 1) - np.clip(ref["rgba"][..., :3], 0, 1)) ** 2)
    psnr = 99.0 if err == 0 else 10 * math.log10(1.0 / err)
    assert psnr >= 50.0, f"{mode}: PSNR {psnr:.1f} dB"


# the seam ---------------------------------------------------------------------------------------------
def _one_pair(left, right):
    """The only pair of floor pixels straddling x = 0 (a row with more, or none, is skipped)."""
    pairs = [(a, a + 1) for a in left if a + 1 in right] + [(a, a - 1) for a in left if a - 1 in right]
    return pairs[0] if len(pairs) == 1 else None


def _row_jumps(folder, program_cache):
    """seam_rows over a top view of the floor (G-buffer rows)."""
    pos, nrm, t_gl, bundles = _gl_transfer(folder, program_cache, 64)
    return seam_rows(pos, nrm, t_gl, bundles, lambda row: (pos[row, :, 3] > 0) & (np.abs(nrm[row, :, 1] - 1.0) < 1e-3)
                     & (np.abs(pos[row, :, 1]) < 1e-4) & (np.abs(pos[row, :, 2]) < 1.2), _one_pair)


def test_mesh_seam_blend_is_continuous_and_hard_switch_is_not(program_cache, tmp_path):
    check_seam(write_mesh_scene, _row_jumps, program_cache, tmp_path)
