"""End-to-end DI shading pipeline (techniques/di_shading: model.py, data.py, train.py, bench.py,
passes/shading_plane.frag).

- The frozen decoder bundle: its 1D latent row equals the di_brdf_disney encoders' 2D lookup at the
  set's constant parameters, and its decoders are the shipped ones (exact lookups).
- The DI Disney shading of a PBR sample stays close to the analytic one (the decoder's accuracy),
  the appearance-filtered reference of a constant set is one analytic shading, and the metallic-path
  clip keeps the value and bounds the GGX lobe's gradient per sample.
- Parity through the driver: the pass writes its G-buffer (fract uv, log2 footprint, hit; duv/dx,
  duv/dy; world point) beside the colour; the torch twin shades exactly those inputs and the learned
  views (end-to-end, independent) must agree within tests/parity.py's 1e-5 rule (exact LUT path).
  The reference view (GL trilinear of RGBA8 + GL mips) is held to the emulated trilinear's bound.
- The trainer (the quick preset with tiny overrides) end to end through the CLI, and the bench on
  that asset; bad input is one clear error.
- Device placement without a GPU: `--device` reaches `train_sweep`, which places the mip chain, data,
  samplers, decoder and every step on it (DeviceSpy: a CPU device that compares unequal to the
  default one, and a tensor-level record of what was put on it; a mix is the error CUDA raises).
"""
import json
import math
import traceback
from pathlib import Path

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from torch.overrides import TorchFunctionMode
from torch.utils.weak import WeakTensorKeyDictionary

from inshade import devices
from inshade.components.lookup_array.torch_twin import LookupArray
from inshade.models import footprint_sampler as fp
from inshade.techniques.di_shading import bench
from inshade.techniques.di_shading import data as plane
from inshade.techniques.di_shading import model as shading
from inshade.techniques.di_shading import train as ds

from parity import assert_parity, check_parity, parity_settings

VIEW = (64, 32)
REPO = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="module")
def decoder():
    return shading.decoder_graph()


@pytest.fixture(scope="module")
def asset(tmp_path_factory):
    out = tmp_path_factory.mktemp("di_shading") / "di_shading_tiny"
    assert ds.main(["-o", str(out), "--preset", "quick", "--size", "32", "--ratio", "2", "--steps", "40",
                    "--samples", "4096", "--views", "2", "--batch", "1024"]) == 0
    return out


def _lanes(n, seed):
    gen = torch.Generator().manual_seed(seed)
    return torch.rand(n, 8, generator=gen)


def _geometry(n, seed):
    gen = torch.Generator().manual_seed(seed)
    p = torch.stack([torch.rand(n, generator=gen) * 6 - 3, torch.zeros(n), -torch.rand(n, generator=gen) * 6], -1)
    return shading.plane_geometry(p, torch.tensor(fp.CAMERA["position"], dtype=torch.float32))


# the frozen decoder --------------------------------------------------------------------------

@settings(max_examples=10, deadline=None)
@given(st.integers(0, 2 ** 31 - 1))
def test_decoder_latents_are_the_encoders_at_the_constants(decoder, seed):
    cells = shading._load_cells(shading.REPO / shading.DEFAULT_BRDF / "encoders.safetensors")
    gen = torch.Generator().manual_seed(seed)
    r = torch.rand(256, 1, generator=gen)
    e_m = LookupArray([64, 64], 2, 32, init=cells["E_m.cells"])
    e_d = LookupArray([64, 64], 2, 32, init=cells["E_d.cells"])
    zero = torch.zeros_like(r)
    with torch.no_grad():
        got = decoder.nodes["enc"](r)
        assert torch.allclose(got[:, :2], e_m(torch.cat([r, zero], -1)), atol=1e-6)
        assert torch.allclose(got[:, 2:], e_d(torch.cat([r, zero], -1)), atol=1e-6)
        assert torch.allclose(decoder.nodes["z_c"](r), cells["E_c.cells"][0, 0].expand(256, 2))


def test_decoders_are_the_shipped_ones(decoder):
    from inshade import bundle as bundle_io
    from inshade.models.graph import GraphModule

    src = GraphModule.from_bundle(bundle_io.load(shading.REPO / shading.DEFAULT_BRDF))
    for name in ("ggx", "smith", "diff", "coef", "gloss"):
        assert torch.equal(decoder.nodes[name].table(), src.nodes[name].table())
    assert not any(p.requires_grad for p in decoder.parameters())


# shading -------------------------------------------------------------------------------------

def test_di_disney_tracks_the_analytic_disney(decoder):
    """The bricks set's texels shaded on plane points: DI decoder vs analytic Disney, display domain.
    The shipped decoder measured 48 dB here; 38 dB fails a broken glue / frame / constant."""
    image = plane.material(32)
    lanes = torch.from_numpy(image.reshape(-1, 8))
    geo = _geometry(len(lanes), 3)
    with torch.no_grad():
        a = shading.display(shading.shade_analytic(lanes, geo))
        b = shading.display(shading.shade_di(lanes, geo, decoder))
    assert 0.05 < float(a.mean()) < 0.9
    mse = float(torch.mean((a - b) ** 2))
    assert 10 * math.log10(1.0 / mse) > 38.0


def test_reference_of_a_constant_set_is_one_shading():
    """16 footprint samples of a constant set are 16 equal analytic shadings (mip levels of a
    constant are the constant, up to the 8-bit rounding of the box means)."""
    value = np.array([0.6, 0.3, 0.2, 0.55, 0.45, 0.9, 0.5, 0.8], np.float32)
    tex = torch.from_numpy(np.broadcast_to(np.round(value * 255) / 255, (32, 32, 8)).copy())
    chain = fp.mip_chain(tex)
    n = 64
    gen = torch.Generator().manual_seed(1)
    uv = torch.rand(n, 2, generator=gen) * 4
    dx, dy = torch.rand(n, 2, generator=gen) * 0.1, torch.rand(n, 2, generator=gen) * 0.1
    geo = _geometry(n, 2)
    got = shading.reference(chain, uv, dx, dy, plane.log2_footprint(dx, dy), geo)
    want = shading.shade_analytic(tex[0, 0].expand(n, 8), geo)
    assert torch.allclose(got, want, rtol=1e-5, atol=1e-6)


@settings(max_examples=6, deadline=None)
@given(st.integers(0, 2 ** 31 - 1), st.sampled_from([1e-6, 1e-3, 1e6]))
def test_metal_clip_keeps_the_value_and_bounds_the_lobe_gradient(decoder, seed, bound):
    lanes = _lanes(128, seed).requires_grad_()
    geo = _geometry(128, seed + 1)
    clipped = shading.shade_di_clipped(lanes, geo, decoder, bound)
    plain = shading.shade_di(lanes, geo, decoder)
    assert torch.allclose(clipped, plain, rtol=1e-5, atol=1e-6)
    (g_clip,) = torch.autograd.grad(clipped.sum(), lanes)
    (g_rest,) = torch.autograd.grad(shading.shade_di(lanes, geo, decoder, no_metal=True).sum(), lanes)
    (g_full,) = torch.autograd.grad(plain.sum(), lanes)
    lobe = g_clip - g_rest
    norm = torch.sqrt((lobe * lobe).sum(-1))
    # the lobe is read back as a difference of two float32 gradients: up to a few ulps of the rest's
    # (|g_rest| reaches ~55 per row: seed 174991 at bound 1e-3 measured 1.2e-6 over a flat 1e-6 slack)
    slack = 1e-6 + 4 * torch.finfo(torch.float32).eps * torch.sqrt((g_rest * g_rest).sum(-1))
    assert bool(torch.all(norm <= bound * (1 + 1e-4) + slack))
    if bound >= 1e6:      # a bound nothing reaches: the full gradient
        assert torch.allclose(g_clip, g_full, rtol=1e-4, atol=1e-5)
    else:
        assert float((g_full - g_rest).norm(dim=-1).max()) > bound * 2   # the clip did bite


def test_nonfinite_gradient_rows_are_dropped_and_counted():
    x = torch.ones(4, 8, requires_grad=True)
    y = x.clone()
    counter = [0]
    y.register_hook(ds._finite_rows(counter))
    w = torch.tensor([1.0, float("nan"), 2.0, float("inf")])[:, None]
    (y * w).sum().backward()
    assert int(counter[0]) == 2
    assert torch.equal(x.grad[:, 0], torch.tensor([1.0, 0.0, 2.0, 0.0]))


def test_training_batches_are_the_same_for_every_lambda():
    tex = fp.texture_tensor(plane.material(32))
    data = plane.plane_samples(fp.mip_chain(tex), 512, 2, seed=0)
    a, b = plane.batches(data, 64, 5), plane.batches(data, 64, 5)
    for _ in range(3):
        x, y = next(a), next(b)
        assert torch.equal(x.x, y.x) and torch.equal(x.ref, y.ref)
    assert data.x[:, 2].min() < -5 and data.x[:, 2].max() > -3       # grazing: a range of footprints
    assert float(data.x[:, :2].min()) >= 0.0 and float(data.x[:, :2].max()) < 1.0


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2 ** 31 - 1))
def test_a_normal_facing_away_from_the_eye_shades_its_visible_side(seed):
    """A bumpy set seen at grazing angles has normals with n.v < 0: shaded as they are, they show
    their unlit back (black speckles near the horizon that the filtered reference does not have).
    visible_normal bends them toward the eye (n.v = MIN_NV before normalising, so at least
    MIN_NV / sqrt(1 + MIN_NV^2) after), unit length, and leaves the others exactly as they are."""
    gen = torch.Generator().manual_seed(seed)
    n = torch.nn.functional.normalize(torch.randn(512, 3, generator=gen), dim=-1)
    v = torch.nn.functional.normalize(torch.randn(512, 3, generator=gen), dim=-1)
    m = shading.visible_normal(n, v)
    nv = (n * v).sum(-1)
    assert torch.allclose(m.norm(dim=-1), torch.ones(512), atol=1e-5)
    assert ((m * v).sum(-1) >= shading.MIN_NV / math.sqrt(1 + shading.MIN_NV ** 2) - 1e-6).all()
    keep = nv >= shading.MIN_NV
    assert torch.equal(m[keep], n[keep])
    assert (~keep).any()


# through the driver --------------------------------------------------------------------------

@parity_settings(3)
@given(st.integers(0, 2 ** 31 - 1))
def test_lookup_graphs_match_torch_exactly(gl, asset, seed):
    """The two new lookup graphs through the generated GLSL (exact LUT path) on random inputs: the
    8-lane footprint sampler (uv, log2 footprint over and beyond the LOD range) and the frozen
    decoder bundle (roughness -> 14 lanes), under the 1e-5 rule."""
    from inshade.bundle import load

    gen = np.random.default_rng(seed)
    x = np.concatenate([gen.random((512, 2)), gen.uniform(-9.0, 1.0, (512, 1))], -1).astype(np.float32)
    check_parity(gl, load(asset / ds.lambda_folder(0.25)), x, what="di_shading sampler (exact)")
    check_parity(gl, load(asset / "brdf"), gen.random((512, 1)).astype(np.float32),
                 what="di_shading decoder bundle (exact)")


def _render(gl, folder, e2e, view):
    from inshade.scene.description import load_scene

    r = bench.ShadingRenderer(gl, folder, e2e, view)
    try:
        return r.render(load_scene(folder).make_camera(), *VIEW)
    finally:
        r.release()


def _twin(folder, sampler, inputs, positions):
    from inshade.scene.description import load_scene

    eye = load_scene(folder).make_camera().uniforms(*VIEW)["u_eye"]
    return bench.torch_twin(folder, sampler, inputs, positions, eye)


@pytest.mark.parametrize("view", ["end_to_end", "independent"])
def test_learned_views_match_the_torch_twin(gl, asset, view):
    scene = json.loads((asset / "scene.json").read_text())
    e2e = scene["networks"][0]["bundle"]
    colour, inputs, _, positions = _render(gl, asset, e2e, view)
    hit = inputs[..., 3] > 0.5
    assert 0.3 < hit.mean() < 1.0
    assert np.ptp(inputs[..., 2][hit]) > 3                          # footprints over several LODs
    sampler = e2e if view == "end_to_end" else ds.lambda_folder(0.0)
    ref = _twin(asset, sampler, inputs, positions)
    assert_parity(colour[..., :3][hit], ref[hit], what=f"di_shading {view} view vs torch")
    assert np.all(colour[..., 3][~hit] == 0)


def test_split_view_is_independent_left_end_to_end_right(gl, asset):
    scene = json.loads((asset / "scene.json").read_text())
    e2e = scene["networks"][0]["bundle"]
    split = _render(gl, asset, e2e, "split")[0]
    left = _render(gl, asset, e2e, "independent")[0]
    right = _render(gl, asset, e2e, "end_to_end")[0]
    w = VIEW[0] // 2
    assert np.array_equal(split[:, :w], left[:, :w]) and np.array_equal(split[:, w:], right[:, w:])
    assert not np.array_equal(left, right)


def test_geometry_twin_matches_the_pass(gl, asset):
    """train.py's plane_pixels (the training data's uv, derivatives and footprints) against the
    pass's G-buffer, to float32 rounding (uv up to ~16 tiles: 2^-19 relative steps)."""
    from inshade.scene.description import load_scene

    _, inputs, derivs, positions = _render(gl, asset, ds.lambda_folder(0.0), "independent")
    uv, dx, dy, p, hit, _ = plane.plane_pixels(load_scene(asset).make_camera().to_dict(), *VIEW)
    ok = bench.plane_rows(inputs)[:, None] & hit.numpy()
    tile = uv.numpy() - np.floor(uv.numpy())
    d = np.abs(tile - inputs[..., :2])
    d = np.minimum(d, 1 - d)                                          # fract wraps
    assert d[ok].max() < 1e-4
    assert np.abs(p.numpy() - positions[..., :3])[ok].max() < 1e-3
    assert np.abs(dx.numpy() - derivs[..., :2])[ok].max() < 1e-4
    assert np.abs(dy.numpy() - derivs[..., 2:])[ok].max() < 1e-4
    lf = plane.log2_footprint(dx, dy).numpy()
    assert np.abs(lf - inputs[..., 2])[ok].max() < 1e-3


@pytest.mark.parametrize("view", ["reference", "trilinear", "analytic"])
def test_uncompressed_views_match_the_emulated_sampler(gl, asset, decoder, view):
    """The views that read the uncompressed set through GL (RGBA8 + GL's mips): the 16-sample
    reference (analytic Disney), one trilinear sample + DI Disney, one + analytic Disney, against
    their torch twins on the emulated trilinear sampler, fed the pass's own inputs. Lanes differ by
    up to the emulation bound of tests/techniques/di_footprint/test_di_footprint.py (~0.02 per lane: 8-bit filter weights,
    llvmpipe's mip blit), which the shading amplifies at highlights: held to a 35 dB display-domain
    PSNR and a mean absolute difference under 2 8-bit steps."""
    from PIL import Image

    colour, inputs, derivs, positions = _render(gl, asset, ds.lambda_folder(0.0), view)
    ok = bench.plane_rows(inputs)[:, None] & (inputs[..., 3] > 0.5)
    set0 = np.asarray(Image.open(asset / "set0.png"), np.float32) / 255
    set1 = np.asarray(Image.open(asset / "set1.png"), np.float32) / 255
    tex = fp.texture_tensor(np.concatenate([set0, set1], -1))
    chain = fp.mip_chain(tex)
    f = lambda a: torch.from_numpy(np.ascontiguousarray(a[ok], np.float32))  # noqa: E731
    x, der, p = f(inputs), f(derivs), f(positions)
    from inshade.scene.description import load_scene

    eye = torch.tensor(load_scene(asset).make_camera().uniforms(*VIEW)["u_eye"], dtype=torch.float32)
    geo = shading.plane_geometry(p[:, :3], eye)
    with torch.no_grad():
        if view == "reference":
            want = shading.reference(chain, x[:, :2], der[:, :2], der[:, 2:], x[:, 2], geo)
        else:
            lanes = fp.emulated_trilinear(chain, x[:, :2], x[:, 2])
            want = shading.shade_di(lanes, geo, decoder) if view == "trilinear" else shading.shade_analytic(lanes, geo)
        want = shading.display(want).numpy()
    got = np.clip(colour[..., :3][ok], 0, 1)
    got = np.where(got <= 0.0031308, 12.92 * got, 1.055 * np.power(np.maximum(got, 0.0031308), 1 / 2.4) - 0.055)
    mse = float(np.mean((got - want) ** 2))
    assert 10 * math.log10(1 / mse) > 35.0
    assert np.mean(np.abs(got - want)) < 2 / 255


# trainer and bench ---------------------------------------------------------------------------

def test_trainer_writes_the_asset_and_the_sweep(asset):
    m = json.loads((asset / "metrics.json").read_text())
    assert m["preset"] == "quick" and m["settings"]["steps"] == 40 and m["settings"]["size"] == 32
    assert [s["lambda"] for s in m["sweep"]] == list(ds.LAMBDAS)
    for s in m["sweep"]:
        assert (asset / ds.lambda_folder(s["lambda"]) / "bundle.json").is_file()
        assert s["psnr_shaded_vs_reference"] > 10
    assert m["lambda_best"] in ds.LAMBDAS and m["lambda_best"] > 0
    for f in ("scene.json", "preview.png", "set0.png", "set1.png", "brdf/bundle.json"):
        assert (asset / f).is_file()
    scene = json.loads((asset / "scene.json").read_text())
    assert scene["networks"][0]["bundle"] == ds.lambda_folder(m["lambda_best"])
    assert scene["networks"][1]["bundle"] == ds.lambda_folder(0.0)


def test_preset_settings_are_what_the_presets_say():
    assert ds.preset_settings("ship")["steps"] == ds.PRESETS["ship"]["steps"]
    assert ds.preset_settings("quick")["size"] == ds.PRESETS["quick"]["size"]
    assert ds.preset_settings("ship")["lambdas"] == list(ds.LAMBDAS)


def test_bench_on_the_asset(gl, asset, tmp_path):
    assert bench.main(["--asset", str(asset), "--out", str(tmp_path), "--width", "64", "--height", "32",
                       "--time-size", "32", "--repeats", "1"]) == 0
    res = json.loads((tmp_path / "di_shading.json").read_text())
    assert [r["lambda"] for r in res["rows"]] == list(ds.LAMBDAS)
    assert res["machine"]["gl_renderer"]
    assert res["parity_end_to_end_scaled_max_err"] <= 1e-5
    assert res["parity_end_to_end_psnr_db"] >= 50.0
    assert {"reference", "end_to_end", "independent"} <= set(res["timing"])
    for r in res["rows"]:
        assert math.isfinite(r["psnr"])
    for f in ("di_shading.md", "di_shading.png", "di_shading_views.png"):
        assert (tmp_path / f).is_file()


@pytest.mark.parametrize("argv, field", [
    (["--lambdas", "0", "1.0"], "lambdas"),
    (["--lambdas", "0.1", "0.5"], "lambdas"),
    (["--size", "48"], "size"),
    (["--brdf", "/nonexistent"], "brdf"),
])
def test_bad_input_is_one_clear_error(tmp_path, capsys, argv, field):
    assert ds.main(["-o", str(tmp_path / "x"), "--steps", "1", "--samples", "64", "--views", "1", *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len([line for line in err if line.startswith("inshade: error:")]) == 1
    assert field in err[-1]


# device placement ----------------------------------------------------------------------------

def _tensors(x):
    if isinstance(x, torch.Tensor):
        yield x
    elif isinstance(x, (list, tuple)):
        for v in x:
            yield from _tensors(v)
    elif isinstance(x, dict):
        for v in x.values():
            yield from _tensors(v)


class DeviceSpy(TorchFunctionMode):
    """A device for a machine without one: `device` is torch.device("cpu", 0), a CPU device that
    compares unequal to the default torch.device("cpu"). A tensor is placed on it when it comes from
    .to(device) (a module's .to(device) included), from a factory given device=device, or from an op
    on a placed tensor; a placed tensor's .device reads `device` (so device=x.device follows it) and
    .cpu() / .to("cpu") take it back off (as on a device, a tensor's move returns a new tensor and
    leaves the source where it was; a module moves its parameters themselves); expand_as / view_as /
    reshape_as follow their first argument only (the other gives a shape). An op that mixes placed
    and unplaced tensors (0-dim ones aside, which CUDA accepts from the CPU) is recorded in `mixed`:
    on a real device it is the "Expected all tensors to be on the same device" error."""

    SHAPE_ONLY = ("expand_as", "view_as", "reshape_as")
    QUERIES = ("_has_compatible_shallow_copy_type",)      # a module's .to asks it of old and new

    def __init__(self):
        super().__init__()
        self.device = torch.device("cpu", 0)
        self.placed = WeakTensorKeyDictionary()
        self.mixed = []

    def on_device(self, t) -> bool:
        return t in self.placed

    @staticmethod
    def _target(func, args, kwargs):
        name = getattr(func, "__name__", "")
        if name == "to":
            return torch._C._nn._parse_to(*args[1:], **kwargs)[0]
        if name in ("cpu", "cuda"):
            return torch.device(name)
        device = kwargs.get("device")
        return None if device is None else torch.device(device)

    def __torch_function__(self, func, types, args=(), kwargs=None):
        kwargs = kwargs or {}
        if getattr(getattr(func, "__self__", None), "__name__", None) == "device" and self.on_device(args[0]):
            return self.device
        out = func(*args, **kwargs)
        if getattr(func, "__name__", "") == "__set__" and isinstance(args[-1], torch.Tensor):
            if self.on_device(args[-1]):    # x.data = y: x is where y is (a module's .to)
                self.placed[args[0]] = True
            else:
                self.placed.pop(args[0], None)
            return out
        target = self._target(func, args, kwargs)
        if target is not None:
            placed = target == self.device
            src = args[0] if args and isinstance(args[0], torch.Tensor) else None
            if out is src and not isinstance(src, torch.nn.Parameter) and self.on_device(src) != placed:
                out = src.view(src.shape)   # a move makes a new tensor; the source stays where it was
        else:
            inputs = args[:1] if getattr(func, "__name__", "") in self.SHAPE_ONLY else (args, kwargs)
            tensors = list(_tensors(inputs))
            placed = any(self.on_device(t) for t in tensors)
            unplaced = any(t.dim() > 0 and not self.on_device(t) for t in tensors)
            if placed and unplaced and getattr(func, "__name__", "") not in self.QUERIES:
                ours = [f for f in traceback.extract_stack() if Path(f.filename).is_relative_to(REPO)
                        and not {"tests", ".venv"} & set(Path(f.filename).parts)]
                here = [f"{Path(f.filename).relative_to(REPO)}:{f.lineno} {f.name}" for f in ours]
                self.mixed.append((getattr(func, "__qualname__", repr(func)), here[-3:]))
        for t in _tensors(out):
            if placed:
                self.placed[t] = True
            elif target is not None:
                self.placed.pop(t, None)    # a module's parameters move off the device in place
        return out


def test_device_spy_catches_a_tensor_left_on_the_cpu():
    """The spy itself: a constant made on the CPU and mixed into a torch.where on the device is
    reported (what CUDA would refuse); unpack (zero normals' fallback included) makes none."""
    spy = DeviceSpy()
    with spy:
        lanes = _lanes(64, 1).to(spy.device)
        torch.where(lanes[:, :1] > 0.5, lanes[:, :3], torch.tensor([0.0, 0.0, 1.0]).expand(64, 3))
        assert len(spy.mixed) == 1 and "where" in spy.mixed[0][0]
        spy.mixed.clear()
        lanes[::7, 3] = 0.5
        lanes[::7, 4:6] = 0.5           # a zero tangent-space normal: the +z fallback
        s = shading.unpack(lanes)
        assert spy.on_device(s["normal_ts"]) and not spy.on_device(lanes.cpu())
        assert not spy.on_device(_lanes(4, 1)) and spy.on_device(lanes) and spy.mixed == []
        lanes.cpu() + lanes                 # a tensor brought back, then mixed with a placed one
    assert len(spy.mixed) == 1


def test_device_option_places_the_sweep_on_the_device(tmp_path, monkeypatch, capsys):
    """`--device cuda` (resolved to the spy's device: no GPU here) reaches train_sweep, which places
    the whole sweep there (data set, references, samplers, decoder, steps, held-out evaluation): no
    op mixes placed and unplaced tensors, every training step's batch, loss, sampler and decoder
    parameters are placed, the results come back to the CPU, and the device is recorded. (The
    batches stay the CPU generator's: the quick preset's bundles are bit-identical to before.)"""
    spy = DeviceSpy()
    seen, steps = {}, []
    real_sweep, real_objective = ds.train_sweep, ds.objective

    def sweep(**kw):
        seen["device"] = kw.get("device")
        with spy:
            runs, decoder, image, info = real_sweep(**kw)
        seen["results"] = [p for r in runs for p in r.graph.parameters()] + list(decoder.parameters())
        return runs, decoder, image, info

    def objective(lam, decoder, *a, **k):
        fn = real_objective(lam, decoder, *a, **k)

        def step(core, b):
            loss = fn(core, b)
            steps.append([spy.on_device(t) for t in (loss, b.x, b.proxy, b.ref, b.geo.l, b.geo.v, b.geo.e,
                                                     *core.parameters(), *decoder.parameters())])
            return loss
        return step

    monkeypatch.setattr(devices, "resolve_device", lambda spec: spy.device if spec == "cuda" else None)
    monkeypatch.setattr(ds, "train_sweep", sweep)
    monkeypatch.setattr(ds, "objective", objective)
    out = tmp_path / "on_device"
    assert ds.main(["-o", str(out), "--device", "cuda", "--size", "32", "--ratio", "2", "--steps", "3",
                    "--samples", "512", "--views", "1", "--batch", "64", "--lambdas", "0", "0.5"]) == 0
    assert "trains on the CPU" not in capsys.readouterr().err
    assert seen["device"] is spy.device
    assert spy.mixed == []
    assert len(steps) == 2 * 3 and all(all(s) for s in steps)
    assert not any(spy.on_device(p) for p in seen["results"])          # back on the CPU for export
    m = json.loads((out / "metrics.json").read_text())
    assert m["device"] == "cpu:0"
    assert json.loads((out / "lambda_050" / "bundle.json").read_text())["provenance"]["device"] == "cpu:0"
