"""Differentiable Indirection training machinery (models/indirection.py): sizing, inits, the
image sampler, a small cascade fit, gradient clipping, the soft-monotonicity regulariser,
post-training quantisation, determinism, and GLSL parity of a trained cascade (exact path)."""
from __future__ import annotations


import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from inshade.models.indirection import (
    INITS, array_bytes, auto_clip_bound, bilinear, cascade, clip_primary_gradients, evaluate_quantised,
    grid_points, image_eval_set, image_sampler, make_array, monotonicity_penalty, primary_nodes,
    size_cascade, train_cascade)
from inshade.components.lookup_array.torch_twin import LookupArray

from parity import check_parity, uniform_inputs


def synthetic_image(n: int = 32) -> np.ndarray:
    """Gradient (R = u, G = v) plus an 4x4-block checker in B: [n, n, 3] in [0, 1]."""
    y, x = np.mgrid[0:n, 0:n]
    r = (x + 0.5) / n
    g = (y + 0.5) / n
    b = 0.2 + 0.6 * (((x // (n // 4)) + (y // (n // 4))) % 2)
    return np.stack([r, g, b], -1).astype(np.float32)


def small_cascade(image, bits=8):
    return cascade(2, 3, 16, 8, primary_bits=bits, cascaded_bits=bits, cascaded_init="mean",
                   cascaded_init_args={"target": image}, input_name="uv", input_semantic="uv",
                   output_name="rgb")


@pytest.fixture(scope="module")
def trained():
    """One short fit shared by the fit, quantisation and parity tests (~300 steps)."""
    image = synthetic_image()
    g = small_cascade(image)
    eval_set = image_eval_set(image)
    with torch.no_grad():
        init = {k: v.clone() for k, v in g.state_dict().items()}
    hist = train_cascade(g, image_sampler(image, 512, seed=1), 300, lr=1e-2, eval_set=eval_set,
                         eval_every=100, seed=0)
    return image, g, hist, eval_set, init


# --- sizing -----------------------------------------------------------------------------------

TEXTURE = dict(primary_dims=2, primary_channels=4, cascaded_dims=4, cascaded_channels=3)


def _bytes(n_p, n_c, primary_dims, primary_channels, cascaded_dims, cascaded_channels, pb=8, cb=8):
    return (array_bytes(n_p, primary_dims, primary_channels, pb)
            + array_bytes(n_c, cascaded_dims, cascaded_channels, cb))


@settings(max_examples=200, deadline=None)
@given(budget=st.integers(1_000, 50_000_000), rho=st.floats(1.0, 128.0),
       pd=st.integers(1, 3), pc=st.integers(1, 4), cd=st.integers(1, 4), cc=st.integers(1, 8),
       pb=st.sampled_from([8, 16, 32]), cb=st.sampled_from([8, 16, 32]))
def test_sizing_multiples_and_budget(budget, rho, pd, pc, cd, cc, pb, cb):
    shape = dict(primary_dims=pd, primary_channels=pc, cascaded_dims=cd, cascaded_channels=cc,
                 primary_bits=pb, cascaded_bits=cb)
    try:
        s = size_cascade(budget, rho, **shape)
    except ValueError as e:
        # only when the smallest configuration (N_c = 4) is over budget
        n_p = max(8, 8 * round(rho * 4 / 8))
        assert _bytes(n_p, 4, pd, pc, cd, cc, pb, cb) > budget
        assert "cannot be met" in str(e)
        return
    assert s.n_primary % 8 == 0 and s.n_cascaded % 4 == 0 and s.n_primary >= 8
    assert s.bytes == _bytes(s.n_primary, s.n_cascaded, pd, pc, cd, cc, pb, cb) <= budget
    assert abs(s.n_primary - rho * s.n_cascaded) <= 4 or s.n_primary == 8  # nearest multiple of 8 to rho N_c
    n_c = s.n_cascaded + 4                                       # the next step is over budget
    assert _bytes(max(8, 8 * round(rho * n_c / 8)), n_c, pd, pc, cd, cc, pb, cb) > budget


def test_sizing_worked_examples():
    # notes §2.2: 1K RGB at 12x with rho = 64 -> N_c = 4, N_p = 256, 262,912 bytes (11.96x),
    # which is 0.3% over the 262,144-byte budget: an error unless slack allows it.
    b = 1024 * 1024 * 3
    with pytest.raises(ValueError, match="cannot be met"):
        size_cascade(b // 12, 64, **TEXTURE)
    s = size_cascade(b // 12, 64, slack=0.01, **TEXTURE)
    assert (s.n_primary, s.n_cascaded, s.bytes) == (256, 4, 262_912)
    assert s.ratio(b) == pytest.approx(11.965, abs=1e-3)
    # 4K RGB at 6x, rho = 128 (supp. Table 2): a 4-channel primary dominates
    s = size_cascade(4096 * 4096 * 3 // 6, 128, **TEXTURE)
    assert s.bytes <= 4096 * 4096 * 3 // 6 and s.n_primary % 8 == 0 and s.n_cascaded % 4 == 0
    assert s.n_primary / s.n_cascaded == pytest.approx(128, rel=0.05)


def test_sizing_errors():
    with pytest.raises(ValueError, match="cannot be met"):
        size_cascade(100, 64, **TEXTURE)
    with pytest.raises(ValueError, match="must be positive"):
        size_cascade(1000, 0, **TEXTURE)


# --- inits ------------------------------------------------------------------------------------

def test_init_table_names():
    assert {"ramp", "constant", "mean", "downsample"} <= set(INITS)
    with pytest.raises(ValueError, match="unknown init"):
        make_array([4, 4], 2, init="nope")


def test_repeated_ramp_is_uvuv():
    m = make_array([16, 16], 4, nonlinearity="triangle")
    x = torch.rand(200, 2)
    torch.testing.assert_close(m(x), torch.cat([x, x], -1), rtol=0, atol=1e-6)
    m3 = make_array([5, 6, 7], 5)
    x3 = torch.rand(100, 3)
    torch.testing.assert_close(m3(x3), torch.cat([x3, x3[:, :2]], -1), rtol=0, atol=1e-6)


@pytest.mark.parametrize("nl", ["none", "triangle", "sinusoid"])
def test_constant_and_mean_read_back_through_f(nl):
    """Inits give the values the array reads back: F^-1 is applied to the cells."""
    m = make_array([4, 4, 4, 4], 3, init="constant", value=[0.5, 0.5, 1.0] if nl != "sinusoid" else [0.5, 0.2, 0.9],
                   nonlinearity=nl)
    want = torch.tensor([0.5, 0.5, 1.0] if nl != "sinusoid" else [0.5, 0.2, 0.9])
    torch.testing.assert_close(m(torch.rand(50, 4)), want.expand(50, 3), rtol=0, atol=1e-6)
    image = synthetic_image()
    m = make_array([8, 8], 3, init="mean", target=image, nonlinearity=nl)
    torch.testing.assert_close(m(torch.rand(20, 2)), torch.from_numpy(image.reshape(-1, 3).mean(0)).expand(20, 3),
                               rtol=0, atol=1e-5)


def test_downsample_init():
    """A linear target survives downsampling exactly (point taps; box taps in the interior),
    from an array or from a callable."""
    f = lambda x: torch.stack([0.2 + 0.5 * x[..., 0] - 0.3 * x[..., 1], x[..., 1] ** 2], -1)  # noqa: E731
    fine = f(grid_points([33, 17]))                                     # [17, 33, 2]
    pts = grid_points([9, 5])
    m = make_array([9, 5], 2, init="downsample", target=fine.numpy(), taps=1)
    torch.testing.assert_close(m.table()[..., 0], f(pts)[..., 0], rtol=0, atol=1e-5)
    boxed = make_array([9, 5], 2, init="downsample", target=fine.numpy()).table()
    torch.testing.assert_close(boxed[1:-1, 1:-1, 0], f(pts)[1:-1, 1:-1, 0], rtol=0, atol=1e-5)
    mc = make_array([9, 5], 2, init="downsample", target=f)
    torch.testing.assert_close(mc.table(), f(pts), rtol=0, atol=1e-6)
    with pytest.raises(ValueError, match="downsample target"):
        make_array([9, 5], 2, init="downsample", target=np.zeros((4, 4, 3)))


def test_cascade_builder_and_redundant_channels():
    g = cascade(2, 3, 16, 4, redundant=2)
    assert g.nodes["primary"].channels == 4 and g.nodes["cascaded"].resolution == [4, 4, 4, 4]
    assert primary_nodes(g) == ["primary"]
    g1 = cascade(1, 2, 8, 4, redundant=1)
    assert g1.nodes["primary"].channels == 2 and len(g1.nodes["cascaded"].resolution) == 2


# --- image sampling ---------------------------------------------------------------------------

def test_bilinear_and_stratified_sampler():
    image = synthetic_image(8)[:6]                                     # 6 x 8, non-square
    uv, rgb = image_eval_set(image)
    torch.testing.assert_close(bilinear(torch.from_numpy(image), uv), rgb, rtol=0, atol=1e-6)
    mid = bilinear(torch.from_numpy(image), torch.tensor([[2.0 / 8, 0.5 / 6]]))
    torch.testing.assert_close(mid[0], torch.from_numpy((image[0, 1] + image[0, 2]) / 2), rtol=0, atol=1e-6)
    x, y = next(image_sampler(image, 48))                              # one epoch: one uv per texel
    cells = (x[:, 1] * 6).floor() * 8 + (x[:, 0] * 8).floor()
    assert sorted(cells.long().tolist()) == list(range(48))
    torch.testing.assert_close(y, bilinear(torch.from_numpy(image), x))
    x2, _ = next(image_sampler(image, 16, stratified=False))
    assert x2.shape == (16, 2) and (x2 >= 0).all() and (x2 < 1).all()


def test_texel_sampler_visits_every_centre_with_its_value():
    from inshade.models.indirection import texel_sampler

    image = synthetic_image(8)[:6]
    uv, rgb = image_eval_set(image)
    x, y = next(texel_sampler(image, 48))
    order = torch.argsort((x[:, 1] * 6).floor() * 8 + (x[:, 0] * 8).floor())
    torch.testing.assert_close(x[order], uv, rtol=0, atol=0)
    torch.testing.assert_close(y[order], rgb, rtol=0, atol=0)


def test_finish_phase_switches_sampler_and_loss():
    from inshade.models.indirection import LOSSES, texel_sampler

    image = synthetic_image(16)
    uv, rgb = image_eval_set(image)

    def run(finish):
        torch.manual_seed(0)
        g = cascade(2, 3, 8, 4, cascaded_init="mean", cascaded_init_args={"target": image})
        h = train_cascade(g, image_sampler(image, 128), 60, lr=1e-2, eval_every=20, eval_set=(uv, rgb),
                          finish=finish)
        return g, h

    g0, h0 = run(None)
    g1, h1 = run((40, texel_sampler(image, 128), "mse"))
    # identical until the switch, different after it; the finish records the squared error
    assert h0.records[2]["psnr"] == h1.records[2]["psnr"]
    assert h1.records[3]["loss"] != h0.records[3]["loss"]
    with torch.no_grad():
        mse = float(LOSSES["mse"](g1(uv) - rgb))
    assert h1.records[3]["loss"] == pytest.approx(mse, rel=0.5)
    with pytest.raises(ValueError, match="unknown loss"):
        train_cascade(g0, image_sampler(image, 16), 1, finish=(0, texel_sampler(image, 16), "huber"))


def test_finish_lbfgs_beats_adam_finish_at_equal_samples():
    """Full-batch L-BFGS on the texel-centre squared error goes further than the minibatch Adam
    finish given the same number of samples, and records its progress after the Adam history."""
    from inshade.models.indirection import LOSSES, finish_lbfgs, texel_sampler

    image = synthetic_image(16)
    uv, rgb = image_eval_set(image)

    def start():
        torch.manual_seed(0)
        g = cascade(2, 3, 8, 4, cascaded_init="mean", cascaded_init_args={"target": image})
        h = train_cascade(g, image_sampler(image, 64), 40, lr=1e-2, eval_every=20, eval_set=(uv, rgb))
        return g, h

    def mse(g):
        with torch.no_grad():
            return float(LOSSES["mse"](g(uv) - rgb))

    adam, _ = start()
    train_cascade(adam, texel_sampler(image, 64), 120, lr=1e-2, loss="mse")   # 120 * 64 samples = 30 * 256
    lbfgs, h = start()
    before = mse(lbfgs)
    finish_lbfgs(lbfgs, (uv, rgb), 30, history=h, first_step=40, eval_every=10)
    assert mse(lbfgs) < 0.9 * mse(adam) and mse(lbfgs) < before, (mse(lbfgs), mse(adam), before)
    steps = [r["step"] for r in h.records]
    assert steps[:3] == [0, 20, 40] and steps[-1] >= 40 + 30 and len(steps) > 4
    assert h.records[-1]["psnr"] == pytest.approx(10 * np.log10(1 / mse(lbfgs)), abs=1e-6)
    assert h.records[-1]["seconds"] >= h.records[2]["seconds"]


# --- training ---------------------------------------------------------------------------------

def test_fit_improves_over_init(trained):
    image, g, hist, eval_set, _ = trained
    psnrs = hist.psnr
    assert [r["step"] for r in hist.records] == [0, 100, 200, 300]
    assert psnrs[-1] > psnrs[0] + 6.0, psnrs                           # mean init ~ 9 dB
    assert hist.loss[-1] < hist.loss[0]
    assert hist.records[-1]["lr"] < 1e-2                               # cosine schedule decayed


def test_determinism():
    image = synthetic_image(16)

    def run(seed, sampler_seed):
        g = cascade(2, 3, 8, 4, cascaded_init="mean", cascaded_init_args={"target": image})
        h = train_cascade(g, image_sampler(image, 64, seed=sampler_seed), 40, seed=seed, eval_every=20,
                          schedule="plateau", monotonicity=0.1)
        return g.nodes["primary"].cells.detach().clone(), h.loss

    a, b, c = run(0, 0), run(0, 0), run(0, 1)
    assert torch.equal(a[0], b[0]) and a[1] == b[1]
    assert not torch.equal(a[0], c[0])


def test_gradient_clipping_limits_primary(monkeypatch):
    image = synthetic_image(16)
    g = cascade(2, 3, 8, 4, cascaded_init="tensor",
                cascaded_init_args={"values": torch.rand(4, 4, 3, generator=torch.Generator().manual_seed(0))})
    x, y = next(image_sampler(image, 256))
    torch.abs(g(x) - y).mean().mul(1e3).backward()
    prim = g.nodes["primary"]
    before = prim.cells.grad.norm(dim=-1)
    assert before.max() > 1e-3
    clip_primary_gradients(g, 1e-3, lr=1e-3, mode="cell")
    after = prim.cells.grad.norm(dim=-1)
    assert after.max() <= 1e-3 * (1 + 1e-5)
    assert torch.allclose(after, before.clamp(max=1e-3), rtol=1e-5, atol=1e-9)  # direction kept, small ones kept
    clip_primary_gradients(g, 1e-4, lr=1e-3, mode="global")
    assert prim.cells.grad.norm() <= 1e-4 * (1 + 1e-5)
    assert auto_clip_bound(LookupArray([11], 1), 1e-3) == pytest.approx(0.1 / 2e-3)  # (N lr)^-1 / 2

    # and the loop applies it before every optimiser step
    seen = []
    step = torch.optim.Adam.step

    def spy(self, *a, **k):
        seen.append(float(prim.cells.grad.norm(dim=-1).max()))
        return step(self, *a, **k)

    monkeypatch.setattr(torch.optim.Adam, "step", spy)
    train_cascade(g, image_sampler(image, 64), 10, clip_primary=1e-5)
    assert len(seen) == 10 and max(seen) <= 1e-5 * (1 + 1e-5)


def test_monotonicity_regulariser():
    ramp = make_array([16, 12], 4, nonlinearity="triangle")
    assert float(monotonicity_penalty(ramp, kappa=1.0).detach()) == 0.0
    flat = make_array([16, 12], 2, init="constant", value=0.5, nonlinearity="triangle")
    assert float(monotonicity_penalty(flat).detach()) == 0.0                    # non-decreasing: zero
    folded = make_array([16, 12], 2, nonlinearity="triangle")
    with torch.no_grad():                                              # u goes up then back down
        u = folded.cells[..., 0]
        folded.cells[..., 0] = torch.where(u > 0.5, 1.0 - u, u)
    pen = monotonicity_penalty(folded, kappa=2.0)
    assert float(pen.detach()) > 0.0
    # value: every fold step drops by 1/15 > |eps| = 0.5/15, contributing 1/15 - 0.5/15
    drops = 7 * 12                                                     # 7 decreasing steps per row
    assert float(pen.detach()) == pytest.approx(2.0 / (16 * 12) * drops * (0.5 / 15), rel=1e-4)
    pen.backward()
    grad = folded.cells.grad[..., 0]
    assert (grad[:, :8] == 0).all() and (grad[:, 8:15] > 0).all()      # only the falling cells are pushed
    folded.cells.grad = None
    central = monotonicity_penalty(folded, kappa=2.0, central=True)
    assert float(central.detach()) == pytest.approx(2 * float(pen.detach()), rel=1e-6)  # each drop seen from both cells
    central.backward()
    grad = folded.cells.grad[..., 0]                                   # the fold's ends pushed apart,
    assert (grad[:, 8] > 0).all() and (grad[:, 15] < 0).all()         # its interior balanced
    assert (grad[:, 9:15] == 0).all() and (grad[:, :8] == 0).all()


# --- quantisation and export ------------------------------------------------------------------

def test_evaluate_quantised(trained):
    _, g, hist, (x, y), _ = trained
    r8 = evaluate_quantised(g, 8, x, y)
    assert r8["psnr_float"] == pytest.approx(hist.psnr[-1], abs=1e-6)
    assert 0.0 <= abs(r8["psnr_drop"]) < 1.0, r8
    r32 = evaluate_quantised(g, 32, x, y)
    assert abs(r32["psnr_drop"]) < 1e-3
    assert g.nodes["primary"].bits == 8                                # restored afterwards
    rmix = evaluate_quantised(g, {"primary": 8, "cascaded": 32}, x, y)
    assert rmix["psnr_quantised"] >= r8["psnr_quantised"] - 0.05


@pytest.mark.parametrize("bits", [8, 32])
def test_trained_cascade_glsl_parity(gl, trained, bits):
    _, g, _, _, _ = trained
    for k in ("primary", "cascaded"):
        g.nodes[k].bits = bits
    try:
        bundle = g.export("di_test")
    finally:
        for k in ("primary", "cascaded"):
            g.nodes[k].bits = 8
    assert bundle.node("primary").params["baked"] == "triangle"
    x = uniform_inputs(bits, 1024, 2, 0.0, 1.0)
    check_parity(gl, bundle, x, lut_filter="exact", what=f"trained cascade {bits}-bit")
