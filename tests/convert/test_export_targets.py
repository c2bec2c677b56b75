"""inshade.export / inshade convert with shading languages beside OpenGL's GLSL: each target's code is
checked on its own driver against the source before anything is written, and the checks are recorded."""
from __future__ import annotations

import contextlib
import io
import warnings

import pytest
import torch

import inshade
from inshade.cli import main
from inshade.convert.lowering import ConvertError
from zoo import zoo

ZOO = zoo()


def test_export_checks_each_target_and_records_it(gl, tmp_path, capsys):
    module, example = ZOO["siren"]
    bundle = inshade.export(module, example, tmp_path / "b", targets=("wgsl", "hlsl"))
    checks = bundle.meta["provenance"]["check"]["targets"]
    assert set(checks) == {"wgsl", "hlsl"} and all(c["ok"] for c in checks.values()), checks
    err = capsys.readouterr().err
    assert "max |wgsl - source|" in err and "max |hlsl - source|" in err and "(rule 1e-05): ok" in err


@pytest.mark.parametrize("targets, message", [
    (("metal",), "target metal: unknown target 'metal'"),
    (("330",), "target 330: 330 is OpenGL's GLSL, which is always checked"),
])
def test_a_target_that_cannot_be_checked_is_refused_in_one_line(gl, tmp_path, targets, message):
    module, example = ZOO["plain"]
    with pytest.raises(ConvertError, match=message) as e:
        inshade.export(module, example, tmp_path / "b", targets=targets, quiet=True)
    assert "\n" not in str(e.value)
    assert not (tmp_path / "b" / "bundle.json").exists()


def test_convert_takes_targets(gl, tmp_path, capsys):
    module, example = ZOO["nerf"]
    path = tmp_path / "nerf.onnx"
    with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
        warnings.simplefilter("ignore")
        torch.onnx.export(module, (example,), path, dynamo=False, input_names=["x"],
                          dynamic_axes={"x": {0: "batch"}})
    assert main(["convert", str(path), "-o", str(tmp_path / "out"), "--target", "vulkan", "--target", "wgsl"]) == 0
    err = capsys.readouterr().err
    assert "max |vulkan - source|" in err and "max |wgsl - source|" in err
