"""The command line: every command has --help, bad input is one line and exit status 2."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
import torch

from inshade import bundle as bundle_mod
from inshade.cli import main
from inshade.models import mlp_graph
from inshade.models.encodings import Frequency

COMMANDS = [[], ["codegen"], ["info"], ["render"], ["doctor"], ["bench"], ["train"],
            ["bench", "mlp"], ["train", "neural_image"]]


@pytest.fixture
def demo_bundle(tmp_path):
    torch.manual_seed(3)
    b = mlp_graph(2, [8, 8], 3, "relu", Frequency(2)).export("neural_field", "demo")
    return b.save(tmp_path / "demo")


@pytest.mark.parametrize("cmd", COMMANDS, ids=lambda c: " ".join(c) or "top")
def test_every_command_has_help(cmd):
    r = subprocess.run([sys.executable, "-m", "inshade.cli", *cmd, "--help"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "usage:" in r.stdout


def test_info_describes_bundle(demo_bundle, capsys):
    assert main(["info", str(demo_bundle)]) == 0
    out = capsys.readouterr().out
    assert "demo" in out and "frequency" in out and "dense" in out


def test_codegen_writes_glsl_manifest_and_resources(demo_bundle, tmp_path, capsys):
    out = tmp_path / "cg" / "net.glsl"
    assert main(["codegen", str(demo_bundle), "--storage", "texture", "--no-gl", "-o", str(out)]) == 0
    report = capsys.readouterr().out
    assert "plan for 'demo'" in report and "texture" in report
    text = out.read_text()
    assert "#include" not in text and "void net_eval(" in text and "inshade_lut" not in text
    manifest = json.loads(out.with_suffix(".glsl.json").read_text())
    assert manifest["plan"]["totals"]["params"] == 8 * 10 + 8 + 8 * 8 + 8 + 3 * 8 + 3
    from safetensors.numpy import load_file
    res = load_file(str(out.with_suffix(".resources.safetensors")))
    assert list(res) == ["net_weights"] and res["net_weights"].dtype == np.float32


def test_codegen_is_deterministic(demo_bundle, tmp_path):
    a, b = tmp_path / "a.glsl", tmp_path / "b.glsl"
    for p in (a, b):
        assert main(["-q", "codegen", str(demo_bundle), "--storage", "inline", "--no-gl", "-o", str(p)]) == 0
    assert a.read_bytes() == b.read_bytes()


def _corrupt(folder, how):
    jpath, wpath = folder / "bundle.json", folder / "weights.safetensors"
    meta = json.loads(jpath.read_text())
    if how == "truncated":
        wpath.write_bytes(wpath.read_bytes()[:-40])
    elif how == "wrong_shape":
        meta["nodes"][1]["params"]["out"] = 9
    elif how == "nan":
        from safetensors.numpy import load_file, save_file
        t = load_file(str(wpath))
        t["l0.weight"][0, 0] = np.nan
        save_file(t, str(wpath))
    elif how == "unknown_type":
        meta["nodes"][0]["type"] = "fancy_layer"
    elif how == "wrong_version":
        meta["version"] = 7
    if how in ("wrong_shape", "unknown_type", "wrong_version"):
        jpath.write_text(json.dumps(meta))


@pytest.mark.parametrize("how,field", [
    ("truncated", "weights.safetensors"), ("wrong_shape", "l0.weight: shape [8, 10] but [9, 10] expected"), ("nan", "l0.weight"),
    ("unknown_type", "unknown component type: fancy_layer"), ("wrong_version", "unsupported version 7"),
])
@pytest.mark.parametrize("command", ["info", "codegen", "render"])
def test_malformed_bundle_is_one_clear_error(demo_bundle, tmp_path, how, field, command):
    _corrupt(demo_bundle, how)
    args = [command, str(demo_bundle)] + (["-o", str(tmp_path / "x.png")] if command == "render" else [])
    r = subprocess.run([sys.executable, "-m", "inshade.cli", "-q", *args], capture_output=True, text=True)
    assert r.returncode == 2, r.stderr
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("inshade: error: "), r.stderr
    assert field in lines[0] and "Traceback" not in r.stderr
    with pytest.raises(bundle_mod.BundleError):
        bundle_mod.load(demo_bundle)


def test_missing_bundle_folder(tmp_path, capsys):
    assert main(["info", str(tmp_path / "nope")]) == 2
    assert "not a bundle folder" in capsys.readouterr().err


def test_doctor_reports_renderer(capsys):
    assert main(["-q", "doctor", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["renderer"] and info["GL_MAX_UNIFORM_BLOCK_SIZE"] >= 16384
    assert isinstance(info["software"], bool)


def test_render_scene_settings_from_the_command_line(tmp_path, capsys):
    from pathlib import Path
    asset = Path(__file__).resolve().parents[1] / "trained" / "sdf_creature"
    a, b = tmp_path / "a.exr", tmp_path / "b.exr"
    assert main(["-q", "render", str(asset), "--width", "32", "--height", "32", "-o", str(a)]) == 0
    assert main(["-q", "render", str(asset), "--width", "32", "--height", "32", "--set", "sky=sunset",
                 "--set", "env_rotation=90", "-o", str(b)]) == 0
    from inshade.runtime.image_io import read_exr
    assert np.abs(read_exr(a) - read_exr(b)).max() > 0.01  # the lighting changed
    sidecar = json.loads(Path(str(b) + ".json").read_text())
    assert "sunset" in json.dumps(sidecar)
    capsys.readouterr()
    assert main(["-q", "render", str(asset), "--set", "bogus=1", "-o", str(a)]) == 2
    assert "unknown setting 'bogus'" in capsys.readouterr().err
