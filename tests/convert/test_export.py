"""Your own network in: plain-torch modules (tests/zoo.py) through inshade.export, and the same
modules through torch.onnx.export and inshade convert; their GLSL against the source through the
driver under the parity rule (tests/parity.py) in every weight storage; hand-built ONNX graphs for
the spellings torch does not emit; and what is refused, in one line, before anything is written."""
from __future__ import annotations

import contextlib
import io
import os
import warnings

import numpy as np
import pytest
import torch
import torch.nn as nn
import torch.nn.functional as F

import inshade
from inshade.bundle import load
from inshade.convert.check import check_inputs, evaluate, source_outputs
from inshade.convert.lowering import ConvertError
from inshade.convert.torch_module import HANDLERS, TRACE_BATCH, _op_name, capture

from parity import assert_parity
from zoo import zoo

ZOO = zoo()
STORAGES = ("inline", "ubo", "texture")
# llvmpipe compiles uniform-block dense layers slowly, and more than linearly in their count (the
# five of residual_ln: ~2 min cold); INSHADE_SLOW=1 runs it
SLOW = {("residual_ln", "ubo")}


def _reference(module, x):
    return source_outputs(module, [x], None)


@pytest.mark.parametrize("name", sorted(ZOO))
def test_zoo_exports_and_matches_torch_in_every_storage(gl, name, tmp_path, capsys):
    module, example = ZOO[name]
    bundle = inshade.export(module, example, tmp_path / name)
    line = capsys.readouterr().err.strip().splitlines()[-1]
    assert line.startswith("max |glsl - source| = ") and line.endswith("(rule 1e-05): ok"), line
    saved = load(tmp_path / name)
    assert saved.digest() == bundle.digest()
    assert saved.meta["provenance"]["check"]["ok"] and saved.meta["provenance"]["source"] == "torch"
    x = check_inputs(example.numpy(), seed=1)
    ref = _reference(module, x)
    for storage in STORAGES:
        if (name, storage) in SLOW and not os.environ.get("INSHADE_SLOW"):
            continue
        out, _, _ = evaluate(saved, x, storage=storage)
        assert_parity(out, ref, what=f"{name} {storage}")


def test_zoo_covers_every_op_export_supports():
    used = set()
    for module, example in ZOO.values():
        trace = example[torch.arange(TRACE_BATCH) % len(example)]
        gm, _, _ = capture(module, (trace,))
        used |= {_op_name(n.target) for n in gm.graph.nodes if n.op == "call_function"}
    required = {"linear", "addmm", "matmul", "relu", "leaky_relu", "sigmoid", "tanh", "softplus", "silu", "gelu",
                "elu", "sin", "cos", "exp", "abs", "clamp", "cat", "slice", "narrow", "split_with_sizes", "chunk",
                "add", "sub", "mul", "div", "linalg_vector_norm", "sum", "layer_norm", "batch_norm", "dropout",
                "grid_sampler", "view", "permute", "transpose", "stack", "flip", "index_select", "softmax", "where",
                "amax", "mean", "pow", "sqrt", "rsqrt"}
    assert required <= used, sorted(required - used)
    assert required <= set(HANDLERS)


@pytest.mark.parametrize("dynamo", [False, True], ids=["torchscript", "dynamo"])
@pytest.mark.parametrize("name", sorted(ZOO))
def test_zoo_through_onnx_matches_onnxruntime(gl, name, dynamo, tmp_path):
    from inshade.convert.export import convert_onnx as convert

    module, example = ZOO[name]
    path = tmp_path / f"{name}.onnx"
    options = ({"dynamic_shapes": ({0: torch.export.Dim("batch")},)} if dynamo
               else {"dynamic_axes": {"x": {0: "batch"}}})
    with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
        warnings.simplefilter("ignore")
        torch.onnx.export(module, (example,), path, dynamo=dynamo, input_names=["x"], **options)
    bundle = convert(path, tmp_path / "out", example=example.numpy(), quiet=True)
    assert bundle.meta["provenance"]["check"]["ok"]
    x = check_inputs(example.numpy(), seed=2)
    out, _, _ = evaluate(load(tmp_path / "out"), x)
    assert_parity(out, source_outputs(path, [x], None), what=f"{name} onnx")


# --- refusals: one line, nothing written ---------------------------------------------------------

class Sorts(nn.Module):
    def __init__(self):
        super().__init__()
        self.blocks = nn.ModuleList([nn.Linear(4, 4), self.Inner()])

    class Inner(nn.Module):
        def __init__(self):
            super().__init__()
            self.fc = nn.Linear(4, 4)

        def forward(self, x):
            return torch.sort(self.fc(x), -1)[0]    # the refused line

    def forward(self, x):
        for block in self.blocks:
            x = block(x)
        return x


class BatchSoftmax(nn.Module):
    def forward(self, x):
        return torch.softmax(x, dim=0)


class Branchy(nn.Module):
    def forward(self, x):
        if x.sum() > 0:
            return x
        return -x


class Conv(nn.Module):
    def __init__(self):
        super().__init__()
        self.conv = nn.Conv2d(1, 2, 3)

    def forward(self, img):
        return self.conv(img).flatten(1)


def _bn_train():
    m = nn.Sequential(nn.Linear(3, 8), nn.BatchNorm1d(8))
    return m.train()


REFUSED = {
    "sort": (Sorts(), torch.rand(8, 4), r"test_export\.py:\d+: blocks\.1: torch\.sort has no shader lowering "
                                        r"\(see inshade convert --ops\)"),
    "softmax_batch": (BatchSoftmax(), torch.rand(8, 4), r"torch\._?softmax: softmax over the batch axis mixes the batch"),
    "batchnorm_train": (_bn_train(), torch.rand(8, 3), r"BatchNorm in train mode normalises over the batch"),
    "python_if": (Branchy(), torch.rand(8, 4), r"test_export\.py:\d+: data-dependent control flow"),
    "conv2d": (Conv(), torch.rand(8, 1, 5, 5), r"conv: torch\.conv2d has no shader lowering"),
    "too_wide": (nn.Linear(3, 40), torch.rand(8, 3), r"outputs: 40 lanes in all; a pass writes at most 32"),
}


@pytest.mark.parametrize("case", sorted(REFUSED))
def test_refused_in_one_line_with_nothing_written(case, tmp_path):
    import re

    module, example, pattern = REFUSED[case]
    folder = tmp_path / "out"
    with pytest.raises(ConvertError) as err:
        inshade.export(module, example, folder, quiet=True)
    message = str(err.value)
    assert "\n" not in message and re.search(pattern, message), message
    assert not folder.exists()


def test_grid_past_the_gl_limits_is_refused(tmp_path):
    class Big(nn.Module):
        def __init__(self):
            super().__init__()
            self.grid = nn.Parameter(torch.rand(1, 4, 128, 128))

        def forward(self, uv):
            return F.grid_sample(self.grid, uv.view(1, 1, -1, 2), align_corners=True)[0, :, 0].t()

    with pytest.raises(ConvertError, match=r"does not fit the GL limits: .*GL_MAX_TEXTURE_SIZE is 64"):
        inshade.export(Big(), torch.rand(8, 2), tmp_path / "out", limits={"GL_MAX_TEXTURE_SIZE": 64}, quiet=True)
    assert not (tmp_path / "out").exists()


def test_existing_folder_needs_force(tmp_path):
    module, example = ZOO["plain"]
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep")
    with pytest.raises(ValueError, match="already holds an asset .notes.txt.; choose another folder, or pass force=True"):
        inshade.export(module, example, tmp_path / "mine", check=False)
    inshade.export(module, example, tmp_path / "mine", check=False, force=True)
    assert (tmp_path / "mine" / "notes.txt").read_text() == "keep" and (tmp_path / "mine" / "bundle.json").is_file()


def test_check_false_records_no_check_and_inshade_check_measures(gl, tmp_path):
    module, example = ZOO["siren"]
    bundle = inshade.export(module, example, tmp_path / "s", check=False, as_="image")
    assert "check" not in bundle.meta["provenance"]
    result = inshade.check(module, tmp_path / "s", example.numpy())
    assert result.ok and result.rows == len(example) and result.max_scaled <= 1e-5
    assert bundle.meta["render"]["program"] == "passes/field2d.frag" and bundle.inputs[0].semantic == "uv"


def test_export_keeps_the_module_mode_and_weights():
    module, example = ZOO["batchnorm_dropout"]
    before = {k: v.clone() for k, v in module.state_dict().items()}
    with torch.no_grad():
        y0 = module(example)
    from inshade.convert.lowering import Lowering
    from inshade.convert.torch_module import TorchLowering

    trace = example[torch.arange(TRACE_BATCH) % len(example)]
    gm, consts, user = capture(module, (trace,))
    TorchLowering(Lowering(), consts, TRACE_BATCH).run(gm, user, [("x", (5,), "generic")])
    assert not module.training
    assert all(torch.equal(before[k], v) for k, v in module.state_dict().items())
    with torch.no_grad():
        assert torch.equal(module(example), y0)
    assert np.isfinite(y0.numpy()).all()


def test_an_exported_bundle_takes_every_codegen_path_and_info(tmp_path, capsys):
    """codegen in every storage and target, info with the envelope, from the CLI."""
    from inshade.cli import main
    from inshade.codegen import GL_TARGETS, OPENGL_STORAGE_MODES

    module, example = ZOO["grid_texture"]
    inshade.export(module, example, tmp_path / "b", check=False, as_="image")
    for storage in OPENGL_STORAGE_MODES:
        for target in GL_TARGETS:
            out = tmp_path / f"{storage}_{target}.glsl"
            assert main(["codegen", str(tmp_path / "b"), "--storage", storage, "--target", target, "-o", str(out),
                         "--no-gl"]) == 0, (storage, target)
            assert "void net_eval(" in out.read_text()
    capsys.readouterr()
    assert main(["info", str(tmp_path / "b")]) == 0
    text = capsys.readouterr().out
    assert "lookup_array" in text and "parity envelope" in text


def test_a_check_whose_literals_would_compile_long_reads_a_texture_and_says_so(gl, tmp_path, capsys, monkeypatch):
    """On a software driver the check draws once, so its JIT is its cost: storage auto's literals past
    the budget are checked from a texture (the same numbers under the rule), and the record says so; a
    storage asked for by name is checked as asked; a GPU driver's check is the plan's own."""
    from inshade.convert import check_storage
    from inshade.runtime.context import machine_limits

    torch.manual_seed(0)
    module = nn.Sequential(nn.Linear(2, 16), nn.ReLU(), nn.Linear(16, 3))
    x = torch.rand(64, 2)
    monkeypatch.setattr(check_storage, "CHECK_COMPILE_BUDGET_S", 0.0)   # every literal is past it
    bundle = inshade.export(module, x, tmp_path / "auto")
    err = capsys.readouterr().err
    software = machine_limits()["software"]
    assert bundle.meta["provenance"]["check"]["storage"] == ("texture" if software else "auto")
    assert ("check: the weights read from a texture" in err) == software
    bundle = inshade.export(module, x, tmp_path / "inline", check_storage="inline")
    assert bundle.meta["provenance"]["check"]["storage"] == "inline"
    assert "read from a texture" not in capsys.readouterr().err
