"""Ground-truth transfer (techniques/prt/transfer.py) and the transfer network's training
(techniques/prt/transfer_training.py): estimator vs closed forms, SDF vs mesh visibility, the cache, training,
checkpoints, export, bad input.

Closed forms: unoccluded, T_k(n) = A_l y_k(n) (``lambert_bands``). A point on a plane under a
sphere of radius r whose centre is h above it along the normal sees everything but a cone of
half-angle asin(r / h) about n, so only the zonal coefficients survive:
T_{l0} = 2 pi sqrt((2l+1) / 4pi) * integral_0^{cos a} t P_l(t) dt.

Tolerances: the estimator uses D cosine-weighted stratified rays; its error is ~1/D per lane for
smooth integrands (measured max 0.017 at D = 256 over random normals), so elementwise 0.03 at
D = 256; a visibility boundary (the cone) adds an O(D^-3/4) stratification error, so 0.04 there.
Meshes: an icosphere of 1280 faces is within 0.2% of the sphere's radius; the same 0.04 holds.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from inshade.models.sdf import SdfModule
from inshade.techniques.prt.transfer import build_dataset, mesh_transfer, sdf_transfer
from inshade.techniques.prt.transfer_dataset import load_dataset
from inshade.techniques.prt.transfer_directions import hemisphere_directions, sphere_directions
from inshade.techniques.prt.transfer_inputs import TransferError
from inshade.techniques.prt.transfer_surface import sample_mesh_surface, sample_sdf_surface
from inshade.techniques.prt.transfer_model import TransferFrame, evaluate_transfer, export_transfer
from inshade.techniques.prt.transfer_net import main
from inshade.techniques.prt.transfer_training import train_transfer, transfer_metrics
from inshade.geometry.sdf import parse_sdf
from inshade.sh import band_of, lambert_bands, sh_basis

pytestmark = pytest.mark.usefixtures("one_torch_thread")


R, H = 0.5, 1.0      # occluder sphere radius and its centre's height above the plane (along +z)


def _scene(root, radius=2.5):
    return parse_sdf({"format": "inshade.geometry.sdf", "version": 1, "bound": {"center": [0, 0, 0], "radius": radius},
                      "root": root})


def _sphere_sdf():
    return SdfModule(_scene({"type": "sphere", "radius": 0.5}, radius=1.0))


def _sphere_over_slab_sdf():
    slab = {"type": "transform", "translate": [0, 0, -0.25], "child": {"type": "box", "size": [2, 2, 0.25]}}
    ball = {"type": "transform", "translate": [0, 0, H], "child": {"type": "sphere", "radius": R}}
    return SdfModule(_scene({"type": "union", "children": [slab, ball]}))


def _sphere_over_slab_mesh():
    import trimesh

    slab = trimesh.creation.box(extents=[4, 4, 0.5])
    slab.apply_translation([0, 0, -0.25])
    ball = trimesh.creation.icosphere(subdivisions=3, radius=R)
    ball.apply_translation([0, 0, H])
    return trimesh.util.concatenate([slab, ball])


def _unoccluded(n):
    a = torch.tensor(lambert_bands(4)[band_of(4)], dtype=torch.float32)
    return a * sh_basis(n, 4, torch)


def _cone_transfer():
    """Transfer at the plane point below the sphere, normal +z: zonal lanes only."""
    cos_a = math.cos(math.asin(R / H))
    t, w = np.polynomial.legendre.leggauss(64)
    t, w = 0.5 * cos_a * (t + 1.0), 0.5 * cos_a * w         # nodes on [0, cos a]
    out = np.zeros(16)
    for l in range(4):
        p_l = np.polynomial.legendre.Legendre.basis(l)(t)
        out[l * l + l] = 2.0 * math.pi * math.sqrt((2 * l + 1) / (4 * math.pi)) * np.sum(w * t * p_l)
    return torch.tensor(out, dtype=torch.float32)


# --- directions and the estimator ---------------------------------------------------------------

def test_sphere_directions_unit_and_balanced():
    d = sphere_directions(512, seed=3)
    assert d.shape == (512, 3) and d.dtype == torch.float32
    assert torch.allclose(d.norm(dim=-1), torch.ones(512), atol=1e-6)
    # low discrepancy: the mean of every SH function but Y_0 is ~0 (random points: ~0.02)
    y = sh_basis(d.double(), 4, torch).mean(0)
    assert y[1:].abs().max() < 2e-3
    assert not torch.equal(d, sphere_directions(512, seed=4))
    assert torch.equal(d, sphere_directions(512, seed=3))


def test_hemisphere_estimator_matches_analytic_unoccluded():
    n = torch.nn.functional.normalize(torch.randn(200, 3, generator=torch.Generator().manual_seed(1)), dim=-1)
    d = hemisphere_directions(n, 256, torch.Generator().manual_seed(0))
    assert ((d * n[:, None]).sum(-1) >= -1e-6).all()                      # upper hemisphere only
    est = sh_basis(d.double(), 4, torch).sum(1) * (math.pi / 256)
    ref = _unoccluded(n).double()
    assert torch.allclose(est[:, 0], torch.full((200,), math.pi * 0.28209479177387814, dtype=torch.float64), atol=1e-6)
    assert (est - ref).abs().max() < 0.03
    assert (est - ref).abs().mean() < 0.004


def test_sdf_transfer_unoccluded_on_a_convex_shape():
    sdf = _sphere_sdf()
    p, n = sample_sdf_surface(sdf, 64, seed=0, resolution=48)
    assert (sdf(p).abs() < sdf.scene.trace["hit_eps"]).all()
    assert torch.allclose(n, torch.nn.functional.normalize(p, dim=-1), atol=1e-3)
    t = sdf_transfer(sdf, p, n, n_dirs=256, seed=0)
    assert t.shape == (64, 16)
    assert (t - _unoccluded(n)).abs().max() < 0.03
    assert abs(float(t[:, 0].mean()) - math.pi * 0.28209479177387814) < 1e-5
    assert float(_unoccluded(torch.tensor([[0.0, 0.0, 1.0]]))[0, 2]) == pytest.approx(1.0233, abs=1e-4)


def test_sdf_transfer_sphere_over_plane_closed_form():
    sdf = _sphere_over_slab_sdf()
    p = torch.zeros(8, 3)
    n = torch.tensor([[0.0, 0.0, 1.0]]).expand(8, 3)
    t = sdf_transfer(sdf, p, n, n_dirs=256, seed=1).mean(0)               # 8 independent estimates
    assert (t - _cone_transfer()).abs().max() < 0.04
    assert float(t[0]) < 0.886 * 0.8                                        # really occluded


def test_mesh_transfer_sphere_over_plane_closed_form_and_matches_sdf():
    mesh = _sphere_over_slab_mesh()
    p = torch.zeros(8, 3)
    n = torch.tensor([[0.0, 0.0, 1.0]]).expand(8, 3)
    t = mesh_transfer(mesh, p, n, n_dirs=256, seed=1).mean(0)
    assert (t - _cone_transfer()).abs().max() < 0.04
    # the same points on both representations: the slab's top and the ball's lower half
    g = torch.Generator().manual_seed(5)
    q = torch.cat([torch.rand(32, 2, generator=g) * 1.6 - 0.8, torch.zeros(32, 1)], -1)
    d = torch.nn.functional.normalize(torch.randn(32, 3, generator=g) * torch.tensor([1.0, 1.0, 0.4]) -
                                      torch.tensor([0.0, 0.0, 0.6]), dim=-1)
    pts = torch.cat([q, torch.tensor([0.0, 0.0, H]) + R * d])
    nrm = torch.cat([torch.tensor([[0.0, 0.0, 1.0]]).expand(32, 3), d])
    ts = sdf_transfer(_sphere_over_slab_sdf(), pts, nrm, n_dirs=256, seed=2)
    tm = mesh_transfer(mesh, pts, nrm, n_dirs=256, seed=2)
    assert (ts - tm).abs().mean() < 0.01
    assert (ts - tm).abs().max() < 0.08                                    # a facet edge near the cone


def test_mesh_samples_use_interpolated_vertex_normals():
    import trimesh

    ball = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    p, n = sample_mesh_surface(ball, 500, seed=0)
    assert p.shape == n.shape == (500, 3)
    assert torch.allclose(n.norm(dim=-1), torch.ones(500), atol=1e-5)
    # smooth normals point along the radius far better than the facets' normals do
    facet = torch.from_numpy(ball.face_normals[ball.nearest.on_surface(p.numpy())[2]]).float()
    radial = torch.nn.functional.normalize(p, dim=-1)
    assert (1 - (n * radial).sum(-1)).mean() < 0.3 * (1 - (facet * radial).sum(-1)).mean()
    # an open mesh (a single quad) is fine: transfer only needs triangles
    quad = trimesh.Trimesh([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], [[0, 1, 2], [0, 2, 3]])
    t = mesh_transfer(quad, *sample_mesh_surface(quad, 4, seed=0), n_dirs=64)
    assert torch.allclose(t[:, 0], torch.full((4,), 0.886227), atol=1e-4)


# --- datasets ---------------------------------------------------------------------------------

def test_dataset_cache_hit_and_key(tmp_path):
    sdf = _sphere_sdf()
    a = build_dataset(sdf, 40, 16, tmp_path, seed=0, progress=False)
    assert not a["cached"] and a["rays_per_second"] > 0 and a["n_dirs"] == 16 and a["seconds"] > 0
    assert a["position"].shape == (40, 3) and a["heldout_transfer"].shape == (2, 16)
    assert a["heldout_dirs"] == 1024 and a["rays"] == 40 * 16 + 2 * 1024
    # the held-out reference is many-ray: on a convex shape it is the closed form to ~1/1024
    assert (a["heldout_transfer"] - _unoccluded(a["heldout_normal"])).abs().max() < 0.006
    b = build_dataset(sdf, 40, 16, tmp_path, seed=0, progress=False)
    assert b["cached"] and b["key"] == a["key"] and b["rays_per_second"] == a["rays_per_second"]
    for k in ("position", "normal", "transfer"):
        assert torch.equal(a[k], b[k])
    c = build_dataset(sdf, 40, 32, tmp_path, seed=0, progress=False)
    assert not c["cached"] and c["key"] != a["key"]
    other = SdfModule(_scene({"type": "sphere", "radius": 0.6}, radius=1.0))
    assert build_dataset(other, 40, 16, tmp_path, seed=0, progress=False)["key"] != a["key"]
    assert len(list(tmp_path.glob("transfer-*.safetensors"))) == 3


def test_dataset_is_deterministic():
    sdf = _sphere_over_slab_sdf()
    a = build_dataset(sdf, 30, 16, None, seed=4, progress=False)
    b = build_dataset(sdf, 30, 16, None, seed=4, progress=False)
    assert torch.equal(a["transfer"], b["transfer"]) and torch.equal(a["position"], b["position"])


# --- training ---------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def small_dataset():
    return build_dataset(_sphere_over_slab_sdf(), 600, 32, None, seed=0, progress=False)


def test_training_reduces_l1_and_exports_a_loadable_bundle(small_dataset, tmp_path):
    from inshade import bundle as bundle_io

    net, frame, m = train_transfer(small_dataset, width=16, layers=2, steps=150, batch=256, lr=5e-3,
                                   progress=False, pos_freqs=2, normal_freqs=2)
    assert m["heldout_l1"] < 0.6 * m["heldout_l1_step0"]
    assert m["heldout_diffuse_psnr"] > m["heldout_diffuse_psnr_step0"]
    assert frame.scale == pytest.approx(1.25) and frame.radius == pytest.approx(2.5)
    out = tmp_path / "bundle"
    export_transfer(net, frame, out, m, {"command": "test"})
    loaded = bundle_io.load(out)
    assert loaded.kind == "prt" and loaded.meta["metrics"]["heldout_l1"] == m["heldout_l1"]
    assert TransferFrame.from_bundle(loaded) == frame
    from inshade.models.graph import GraphModule

    again = GraphModule.from_bundle(loaded)
    p, n = small_dataset["position"][:50], small_dataset["normal"][:50]
    with torch.no_grad():
        assert torch.allclose(evaluate_transfer(again, frame, p, n), evaluate_transfer(net, frame, p, n), atol=1e-6)


def test_a_lower_precision_ends_with_a_fine_tune_and_exports_what_it_saw(small_dataset, tmp_path):
    """precision i8: the fit ends with a quantization-aware fine-tune; the exported bundle's dense layers are
    int8 codes times row scales and compute what the fine-tuned network computed through the quantizer."""
    from inshade import bundle as bundle_io
    from inshade.models.graph import GraphModule
    from inshade.models.quantize_aware import quantizer_in_loop

    net, frame, m = train_transfer(small_dataset, width=16, layers=2, steps=60, batch=256, lr=5e-3, progress=False,
                                   pos_freqs=2, normal_freqs=2, precision="i8", finetune_steps=30)
    assert m["finetune_steps"] == 30 and "heldout_l1_quantized_without_finetune" in m
    export_transfer(net, frame, tmp_path / "b", m, {"command": "test"}, precision="i8")
    loaded = bundle_io.load(tmp_path / "b")
    assert {n.params.get("precision") for n in loaded.nodes if n.type == "dense"} == {"i8"}
    p, n = small_dataset["position"][:50], small_dataset["normal"][:50]
    with torch.no_grad(), quantizer_in_loop(net, "i8"):
        seen = evaluate_transfer(net, frame, p, n)
    with torch.no_grad():
        assert torch.equal(evaluate_transfer(GraphModule.from_bundle(loaded), frame, p, n), seen)


def test_checkpoint_resume_equals_uninterrupted(small_dataset, tmp_path):
    kw = dict(width=8, layers=2, steps=40, batch=128, progress=False, pos_freqs=1, normal_freqs=1)
    whole, _, _ = train_transfer(small_dataset, **kw)
    ck = tmp_path / "ck.safetensors"
    train_transfer(small_dataset, checkpoint=ck, checkpoint_every=7, until=20, **kw)
    resumed, _, m = train_transfer(small_dataset, checkpoint=ck, **kw)
    assert m["resumed_from"] == 20
    for (k, a), b in zip(whole.state_dict().items(), resumed.state_dict().values()):
        assert torch.allclose(a, b, atol=1e-6), k
    with pytest.raises(ValueError, match="config.width"):
        train_transfer(small_dataset, checkpoint=ck, **{**kw, "width": 12})


def test_metrics_identity():
    t = torch.rand(10, 16)
    m = transfer_metrics(t, t)
    assert m["l1"] == 0 and m["psnr"] == 99.0 and m["diffuse_psnr"] == 99.0


def test_cli_writes_a_bundle(tmp_path):
    import json

    scene = tmp_path / "sdf.json"
    scene.write_text(json.dumps({"format": "inshade.geometry.sdf", "version": 1, "name": "ball",
                                 "bound": {"center": [0, 0, 0], "radius": 1.0},
                                 "root": {"type": "sphere", "radius": 0.5}}))
    out = tmp_path / "out"
    assert main(["--sdf", str(scene), "--out", str(out), "--points", "200", "--dirs", "8", "--steps", "20",
                 "--width", "8", "--layers", "1", "--batch", "64"]) == 0
    from inshade import bundle as bundle_io

    b = bundle_io.load(out)
    assert b.name == "ball_transfer" and "train_seconds" in b.meta["metrics"]
    assert "rays_per_second" in b.meta["metrics"] and "--sdf" in b.meta["provenance"]["command"]
    cache = sorted(p.name for p in (tmp_path / ".transfer_cache").iterdir())
    assert [n.split("-")[0] for n in cache] == ["checkpoint", "transfer"]
    assert sorted(p.name for p in out.iterdir()) == ["bundle.json", "weights.safetensors"]
    # a rerun finds the dataset cached and the checkpoint done
    assert main(["--sdf", str(scene), "--out", str(out), "--points", "200", "--dirs", "8", "--steps", "20",
                 "--width", "8", "--layers", "1", "--batch", "64"]) == 0
    assert bundle_io.load(out).meta["metrics"]["resumed_from"] == 20


# --- bad input --------------------------------------------------------------------------------

def test_bad_points_are_one_clear_error():
    sdf = _sphere_sdf()
    p, n = torch.zeros(4, 3), torch.tensor([[0.0, 0.0, 1.0]]).expand(4, 3).clone()
    bad = p.clone()
    bad[2, 1] = float("nan")
    with pytest.raises(TransferError, match="NaN/inf position or normal .first at index 2"):
        sdf_transfer(sdf, bad, n)
    with pytest.raises(TransferError, match=r"must be \[N, 3\]"):
        sdf_transfer(sdf, torch.zeros(4, 2), n)
    with pytest.raises(TransferError, match="normals must match"):
        sdf_transfer(sdf, p, n[:3])
    with pytest.raises(TransferError, match="is zero"):
        sdf_transfer(sdf, p, torch.zeros(4, 3))
    with pytest.raises(TransferError, match="n_dirs"):
        sdf_transfer(sdf, p, n, n_dirs=0)
    with pytest.raises(TransferError, match="not an SDF module"):
        sdf_transfer(object(), p, n)
    with pytest.raises(TransferError, match="trimesh.Trimesh"):
        mesh_transfer(sdf, p, n)
    with pytest.raises(TransferError, match="no surface inside the bound"):
        sample_sdf_surface(SdfModule(_scene({"type": "sphere", "radius": 0.5}, radius=0.2)), 10)


def test_bad_files_are_one_clear_error(tmp_path):
    junk = tmp_path / "junk.safetensors"
    junk.write_bytes(b"\x00" * 16)
    with pytest.raises(TransferError, match="junk.safetensors: unreadable"):
        load_dataset(junk)
    with pytest.raises(TransferError, match="nope.ply: mesh: no such file"):
        main(["--mesh", str(tmp_path / "nope.ply"), "--out", str(tmp_path / "o")])
    bad = tmp_path / "bad.ply"
    bad.write_text("ply\nformat ascii 1.0\nelement vertex 2\nend_header\n0 0\n")
    with pytest.raises(TransferError, match="bad.ply: mesh:"):
        main(["--mesh", str(bad), "--out", str(tmp_path / "o")])
    with pytest.raises(ValueError, match="dataset: transfer: contains NaN"):
        train_transfer({"position": torch.zeros(4, 3), "normal": torch.ones(4, 3),
                        "transfer": torch.full((4, 16), float("nan")), "center": [0, 0, 0], "radius": 1.0})


def test_neural_sdf_geometry_through_the_cli(tmp_path):
    """Any module with the SDF interface works: a network SDF (models/network_sdf.py) whose one
    dense layer is the plane z = -0.1 sees the whole hemisphere, so its transfer is the closed form."""
    from inshade.models import network_sdf as nsdf
    from inshade import bundle as bundle_io
    from inshade.models.graph import GraphModule

    g = GraphModule([("position", 3, "position")])
    g.output("distance", g.dense("l0", "position", 1), "sdf")
    with torch.no_grad():
        g.nodes["l0"].linear.weight.copy_(torch.tensor([[0.0, 0.0, 1.0]]))
        g.nodes["l0"].linear.bias.fill_(0.1)
    module = nsdf.NetworkSdfModule(g, trace={"max_steps": 64, "step_scale": 0.9, "hit_eps": 1e-3,
                                             "normal_eps": 1e-3}, radius=1.0, name="plane")
    module.export(name="plane").save(tmp_path / "plane")
    loaded = nsdf.NetworkSdfModule.from_bundle(bundle_io.load(tmp_path / "plane"))
    data = build_dataset(loaded, 60, 8, None, progress=False, holdout=3)
    assert torch.allclose(data["position"][:, 2], torch.full((60,), -0.1), atol=1e-3)
    assert (data["heldout_transfer"] - _unoccluded(data["heldout_normal"])).abs().max() < 0.006
    out = tmp_path / "out"
    assert main(["--neural-sdf", str(tmp_path / "plane"), "--out", str(out), "--points", "60", "--dirs", "8",
                 "--steps", "5", "--width", "8", "--layers", "1"]) == 0
    assert bundle_io.load(out).name == "plane_transfer"


def test_drop_enclosed_removes_fully_occluded_samples():
    """--drop-enclosed: samples whose every ray is blocked (band 0 exactly 0) leave training and
    the held-out set; partly occluded ones stay."""
    from inshade.techniques.prt.transfer_training import _without_enclosed

    t = torch.rand(6, 16) + 0.1
    t[[1, 4], :] = 0.0
    t[2, 0] = 1e-3                       # nearly but not fully occluded: kept
    data = {"position": torch.randn(6, 3), "normal": torch.randn(6, 3), "transfer": t,
            "heldout_position": torch.randn(2, 3), "heldout_normal": torch.randn(2, 3),
            "heldout_transfer": torch.stack([torch.zeros(16), torch.ones(16)])}
    out = _without_enclosed(data)
    assert out["transfer"].shape[0] == 4 and bool((out["transfer"][:, 0] > 0).all())
    assert torch.equal(out["position"], data["position"][[0, 2, 3, 5]])
    assert out["heldout_transfer"].shape[0] == 1 and data["transfer"].shape[0] == 6   # input untouched
