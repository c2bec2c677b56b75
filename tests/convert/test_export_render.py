"""From user code to pixels: a SIREN fitted to an image, a NeRF-style MLP and an SDF network, written
in plain torch, exported with ``as_=`` and drawn by ``inshade render`` (EXR, linear) through the
generic programs (the 2D field pass, the sphere tracer, the field march), each against a torch
evaluation of the same view with the user's own module (>= 50 dB)."""
from __future__ import annotations

import math

import numpy as np
import pytest
import torch

import inshade
from inshade.cli import main
from inshade.convert.lowering import ConvertError
from inshade.scene.image_io import read_exr
from inshade.scene.description import load_scene

from zoo import Siren, zoo

SIZE = 64


def psnr(a, b) -> float:
    mse = float(np.mean((np.asarray(a, np.float64) - np.asarray(b, np.float64)) ** 2))
    return math.inf if mse == 0 else 10 * math.log10(1.0 / mse)


def _render(folder, tmp_path) -> np.ndarray:
    out = tmp_path / "shot.exr"
    assert main(["render", str(folder), "-o", str(out), "--width", str(SIZE), "--height", str(SIZE)]) == 0
    return read_exr(out)[..., :3]


def fitted_siren(steps=150):
    """A SIREN fitted (briefly) to the astronaut photograph at 32^2, as a user would."""
    from skimage import data, transform

    torch.manual_seed(0)
    image = transform.resize(data.astronaut(), (32, 32), anti_aliasing=True).astype(np.float32)
    h, w = image.shape[:2]
    ys = (h - 0.5 - np.arange(h)) / h          # uv (0, 0) is the bottom-left corner
    xs = (np.arange(w) + 0.5) / w
    uv = torch.from_numpy(np.stack(np.meshgrid(xs, ys), -1).reshape(-1, 2).astype(np.float32))
    target = torch.from_numpy(image.reshape(-1, 3))
    net = Siren(hidden=32, layers=3)
    opt = torch.optim.Adam(net.parameters(), lr=1e-3)
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        for _ in range(steps):
            loss = ((net(uv) - target) ** 2).mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
    finally:
        torch.set_num_threads(threads)
    return net.eval(), uv, loss.item()


def test_siren_image(gl, tmp_path):
    net, uv, loss = fitted_siren()
    assert loss < 0.02, f"the fit did not fit ({loss})"
    inshade.export(net, uv, tmp_path / "siren", as_="image", quiet=True)
    shot = _render(tmp_path / "siren", tmp_path)
    ys = (SIZE - 0.5 - np.arange(SIZE)) / SIZE
    xs = (np.arange(SIZE) + 0.5) / SIZE
    grid = torch.from_numpy(np.stack(np.meshgrid(xs, ys), -1).reshape(-1, 2).astype(np.float32))
    with torch.no_grad():
        ref = net(grid).numpy().reshape(SIZE, SIZE, 3)
    assert psnr(shot, ref) >= 50.0, psnr(shot, ref)


def test_an_image_network_says_its_colour_or_is_warned(gl, tmp_path, capsys):
    """The SIREN fitted to the photograph's pixels (sRGB values, as files hold them): exported as an
    image with no colour said, it is taken as linear light and a warning names colour="srgb"; with
    colour="srgb" the PNG holds the network's own values (>= 50 dB against torch, 8-bit), where
    the linear reading shows it pale."""
    from PIL import Image

    net, uv, _ = fitted_siren()
    inshade.export(net, uv, tmp_path / "assumed", as_="image")
    err = capsys.readouterr().err
    assert 'colour="srgb"' in err and "taken as linear light" in err, err
    inshade.export(net, uv, tmp_path / "said", as_="image", colour="srgb")
    assert "taken as linear light" not in capsys.readouterr().err
    ys = (SIZE - 0.5 - np.arange(SIZE)) / SIZE
    xs = (np.arange(SIZE) + 0.5) / SIZE
    grid = torch.from_numpy(np.stack(np.meshgrid(xs, ys), -1).reshape(-1, 2).astype(np.float32))
    with torch.no_grad():
        want = np.clip(net(grid).numpy().reshape(SIZE, SIZE, 3), 0.0, 1.0)
    shots = {}
    for name in ("assumed", "said"):
        out = tmp_path / f"{name}.png"
        assert main(["render", str(tmp_path / name), "-o", str(out), "--width", str(SIZE), "--height",
                     str(SIZE)]) == 0
        shots[name] = np.asarray(Image.open(out).convert("RGB"), np.float64) / 255.0
    assert psnr(shots["said"], want) >= 50.0, psnr(shots["said"], want)
    assert psnr(shots["assumed"], want) < 25.0 and shots["assumed"].mean() > want.mean() + 0.1


def test_colour_goes_with_an_image(tmp_path):
    module, example = zoo()["sdf"]
    with pytest.raises(ConvertError, match='colour: goes with as_="image"'):
        inshade.export(module, example, tmp_path / "x", as_="sdf", colour="srgb", check=False)
    with pytest.raises(ConvertError, match="colour: 'sRGB' is not one of linear, srgb"):
        inshade.export(module, example, tmp_path / "y", as_="image", colour="sRGB", check=False)


def test_sdf(gl, tmp_path):
    from inshade.codegen.network_sdf import NetworkSdfScene
    from inshade.codegen.sdf import environment_sh
    from inshade.models.sdf import render

    module, example = zoo()["sdf"]
    bundle = inshade.export(module, example, tmp_path / "sdf", as_="sdf", quiet=True)
    shot = _render(tmp_path / "sdf", tmp_path)

    class UserSdf(torch.nn.Module):   # the user's module as the reference renderer's scene
        scene = NetworkSdfScene.from_bundle(bundle)

        def forward(self, p):
            return module(p)[..., 0]

        def albedo(self, p):
            return torch.tensor(self.scene.albedo).expand(p.shape[0], 3)

    scene = load_scene(tmp_path / "sdf")
    ref = render(UserSdf(), scene.make_camera().uniforms(SIZE, SIZE), SIZE, SIZE, environment_sh("noon", 0.0))
    assert 0.03 < ref["hit"].mean() < 0.9, "the surface should fill part of the frame"
    assert psnr(shot, ref["rgba"][..., :3]) >= 50.0, psnr(shot, ref["rgba"][..., :3])


def test_nerf_field(gl, tmp_path):
    from inshade.codegen.field import field_settings
    from inshade.techniques.imported.march import march

    module, example = zoo()["nerf"]
    bundle = inshade.export(module, example, tmp_path / "field", as_="field", quiet=True)
    shot = _render(tmp_path / "field", tmp_path)
    scene = load_scene(tmp_path / "field")
    ref = march(module, field_settings(bundle), scene.make_camera().uniforms(SIZE, SIZE), SIZE, SIZE)[..., :3]
    assert ref.std() > 0.01, "the field should not be empty"
    assert psnr(shot, ref) >= 50.0, psnr(shot, ref)


def test_an_srgb_output_is_decoded_for_display(gl, tmp_path):
    """A network fitted to sRGB pixels says so (semantics={"y": "srgb"}): the display decodes its colour
    to linear, so the PNG shows the photograph, not a washed-out one."""
    from inshade.metrics import srgb_eotf

    net, uv, _ = fitted_siren(steps=60)
    inshade.export(net, uv, tmp_path / "s", as_="image", semantics={"y": "srgb"}, quiet=True)
    shot = _render(tmp_path / "s", tmp_path)
    ys = (SIZE - 0.5 - np.arange(SIZE)) / SIZE
    xs = (np.arange(SIZE) + 0.5) / SIZE
    grid = torch.from_numpy(np.stack(np.meshgrid(xs, ys), -1).reshape(-1, 2).astype(np.float32))
    with torch.no_grad():
        ref = srgb_eotf(np.clip(net(grid).numpy(), 0, 1)).reshape(SIZE, SIZE, 3)
    assert psnr(shot, ref) >= 50.0, psnr(shot, ref)
