"""The command line: every command has --help, bad input is one line and exit status 2."""
from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import torch

from inshade import bundle as bundle_mod
from inshade.cli import main
from inshade.components.encodings.torch_twin import Frequency
from inshade.models import mlp_graph

REPO = Path(__file__).resolve().parents[1]
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
    err = capsys.readouterr().err
    assert "does not exist" in err and "not a bundle folder" not in err


# assets by name, info/codegen on asset folders ------------------------------------------------
def test_asset_by_name_from_anywhere(tmp_path, monkeypatch, capsys):
    from inshade.scene.description import resolve_asset
    monkeypatch.chdir(tmp_path)
    assert resolve_asset("prt_creature") == REPO / "trained" / "prt_creature"
    assert main(["-q", "render", "sdf_creature", "--width", "8", "--height", "8", "-o", "x.png"]) == 0
    assert (tmp_path / "x.png").is_file()
    capsys.readouterr()
    assert main(["info", "prt_creatur"]) == 2
    err = capsys.readouterr().err
    assert "prt_creatur: does not exist" in err and "prt_creature" in err


def test_assets_env_folders(tmp_path, monkeypatch, demo_bundle, capsys):
    from inshade.scene.description import resolve_asset
    monkeypatch.chdir(tmp_path / "demo")   # a bare name that is not a path here
    monkeypatch.setenv("INSHADE_ASSETS", f"{tmp_path / 'none'}{os.pathsep}{tmp_path}")
    assert resolve_asset("demo") == tmp_path / "demo"
    assert main(["info", "demo"]) == 0 and "frequency" in capsys.readouterr().out


def test_info_prt_asset_follows_scene(capsys):
    assert main(["-q", "info", "prt_neural_bunny"]) == 0
    out = capsys.readouterr().out
    assert "== network (prefix transfer)" in out and "== network SDF (prefix sdfnet)" in out
    assert "settings (" in out and "exposure" in out and "sunset|overcast|noon|studio" in out
    assert "default noon" in out and "-180..180" in out


def test_info_analytic_sdf_asset_has_no_networks(capsys):
    assert main(["-q", "info", "sdf_creature"]) == 0
    out = capsys.readouterr().out
    assert "networks: none" in out and "analytic SDF 'creature'" in out and "env_rotation" in out
    assert main(["-q", "info", "sdf_creature", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["bundles"] == [] and data["scene"]["settings"]["sky"]["choices"]


def test_info_summarises_training_history(capsys):
    assert main(["-q", "info", "di_texture_astronaut"]) == 0
    out = capsys.readouterr().out
    bundle = json.loads((REPO / "trained" / "di_texture_astronaut" / "bundle.json").read_text())
    records = len(bundle["metrics"]["history"])
    assert f"history: {records} values" in out and "--json has them in full" in out
    assert main(["-q", "info", "di_texture_astronaut", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert len(data["bundles"][0]["meta"]["metrics"]["history"]) == records


def test_codegen_on_assets(tmp_path, capsys):
    assert main(["-q", "codegen", "prt_neural_bunny", "--no-gl"]) == 2
    err = capsys.readouterr().err
    assert "--network PREFIX" in err and "transfer, sdfnet" in err and len(err.strip().splitlines()) == 1
    out = tmp_path / "t.glsl"
    assert main(["-q", "codegen", "prt_neural_bunny", "--network", "transfer", "--no-gl", "-o", str(out)]) == 0
    assert "void transfer_eval(" in out.read_text()
    assert main(["-q", "codegen", "prt_creature", "--no-gl"]) == 0   # one network: no --network needed
    capsys.readouterr()
    assert main(["-q", "codegen", "sdf_creature", "--no-gl"]) == 2
    assert "uses no networks" in capsys.readouterr().err


# no tracebacks: Ctrl+C, a closed pipe; -q after the command; --help defaults once ------------
def test_ctrl_c_is_quiet(tmp_path):
    p = subprocess.Popen([sys.executable, "-m", "inshade.cli", "render", "prt_creature", "--width", "2048",
                          "--height", "2048", "-o", str(tmp_path / "x.png")],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    line = p.stderr.readline()   # the GL context line: the command is under way
    assert line.startswith("inshade: "), line
    time.sleep(0.5)
    p.send_signal(signal.SIGINT)
    out, err = p.communicate(timeout=120)
    assert p.returncode == 130, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    assert not (tmp_path / "x.png").exists()


@pytest.mark.parametrize("cmd", [["train", "neural_image", "--help"], ["info", "prt_creature"]],
                         ids=["train-help", "info"])
def test_closed_pipe_is_quiet(cmd):
    p = subprocess.Popen([sys.executable, "-m", "inshade.cli", *cmd], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE)
    p.stdout.close()   # like `| head -0`: the reader is gone before anything is written
    err = p.stderr.read().decode()
    p.wait(timeout=120)
    assert p.returncode in (0, 141), err
    assert "Traceback" not in err and "BrokenPipe" not in err and "Exception ignored" not in err, err


def test_quiet_after_the_command(demo_bundle):
    r = subprocess.run([sys.executable, "-m", "inshade.cli", "render", "sdf_creature", "-q", "--width", "8",
                        "--height", "8", "-o", str(demo_bundle / "x.png")], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert not [ln for ln in r.stderr.splitlines() if not ln.startswith("wrote ")], r.stderr


def test_no_opengl_accelerate_notice():
    r = subprocess.run([sys.executable, "-c", "import sys; from inshade.cli import main; "
                        "sys.argv[1:] = ['doctor']; import logging; main(['doctor']); import OpenGL.GL"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "OpenGL_accelerate" not in r.stderr


def _option_helps(text: str) -> list[str]:
    """Each option's entry of an argparse --help, joined into one line."""
    blocks = []
    for line in text.splitlines():
        if line.startswith("  -"):
            blocks.append([line])
        elif blocks and blocks[-1] is not None and line.startswith("   "):
            blocks[-1].append(line)
        elif blocks:
            blocks.append(None)
    return [" ".join(" ".join(b).split()) for b in blocks if b]


def test_help_shows_each_default_once(capsys):
    from inshade.cli import benches, trainers
    said = re.compile(r"[(;,]\s*default\b", re.I)
    for group, table in (("train", trainers()), ("bench", benches())):
        for name in table:
            with pytest.raises(SystemExit):
                main([group, name, "--help"])
            for entry in _option_helps(capsys.readouterr().out):
                assert len(said.findall(entry)) <= 1, f"inshade {group} {name} --help: {entry}"


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
    from inshade.scene.image_io import read_exr
    assert np.abs(read_exr(a) - read_exr(b)).max() > 0.01  # the lighting changed
    sidecar = json.loads(Path(str(b) + ".json").read_text())
    assert "sunset" in json.dumps(sidecar)
    capsys.readouterr()
    assert main(["-q", "render", str(asset), "--set", "bogus=1", "-o", str(a)]) == 2
    assert "unknown setting 'bogus'" in capsys.readouterr().err


@pytest.mark.parametrize("argv, line", [
    (["view", "trained/neural_image"], "inshade: error: inshade view needs imgui-bundle (not installed): pip install -e '.[view]'"),
    (["bench", "mlp", "--quick", "--out", "{tmp}/b"], "inshade: error: inshade bench mlp needs torch (not installed): pip install -e '.[bench]'"),
    (["train", "neural_image", "--out", "{tmp}/t"], "inshade: error: inshade train neural_image needs torch (not installed): pip install -e '.[train]'"),
    (["convert", "{tmp}/m.onnx", "-o", "{tmp}/c"], "inshade: error: reading ONNX needs the onnx package: pip install -e '.[onnx]'"),
])
def test_a_missing_extra_is_one_line_naming_it(argv, line, tmp_path):
    """A runtime-only install (pip install -e .): the optional modules are blocked in a fresh interpreter."""
    import subprocess
    import sys

    (tmp_path / "m.onnx").write_bytes(b"x")
    code = ("import sys\nfor m in ('imgui_bundle', 'torch', 'onnx', 'onnxruntime'): sys.modules[m] = None\n"
            "from inshade.cli import main\nsys.exit(main(sys.argv[1:]))")
    proc = subprocess.run([sys.executable, "-c", code, *[a.format(tmp=tmp_path) for a in argv]], capture_output=True,
                          text=True, timeout=120, cwd=REPO)
    lines = [x for x in proc.stderr.splitlines() if not x.startswith("inshade: OpenGL context")]
    assert proc.returncode == 2 and lines == [line], proc.stderr[-2000:]
    assert not (tmp_path / "b").exists() and not (tmp_path / "t").exists() and not (tmp_path / "c").exists()


def test_dash_output_streams_to_stdout(tmp_path, capfdbinary):
    """-o - : codegen the GLSL alone (the plan on stderr), render a PNG (no sidecar), eval a .npy; a
    GLSL that binds resources cannot go there (one line). Nothing named '-' is written."""
    import io

    import numpy as np
    from PIL import Image

    from inshade.cli import main

    from inshade.models import mlp_graph

    asset = REPO / "trained" / "neural_image"
    mlp = tmp_path / "mlp"
    mlp_graph(2, [8], 3).export("demo", "demo").save(mlp)
    capfdbinary.readouterr()
    assert main(["codegen", str(mlp), "--storage", "inline", "--no-gl", "-o", "-"]) == 0
    out, err = capfdbinary.readouterr()
    assert b"void net_eval(" in out and b"plan for" not in out and b"plan for" in err
    assert main(["codegen", str(asset), "--storage", "texture", "--no-gl", "-o", "-"]) == 2
    out, err = capfdbinary.readouterr()
    assert out == b"" and err.count(b"\n") == 1 and b"-o -: this GLSL binds" in err
    assert main(["-q", "render", str(asset), "-o", "-", "--width", "32", "--height", "32"]) == 0
    out, _ = capfdbinary.readouterr()
    assert Image.open(io.BytesIO(out)).size == (32, 32)
    np.save(tmp_path / "x.npy", np.random.default_rng(0).random((5, 2), np.float32))
    assert main(["-q", "eval", str(asset), str(tmp_path / "x.npy"), "-o", "-"]) == 0
    out, _ = capfdbinary.readouterr()
    assert np.load(io.BytesIO(out)).shape == (5, 3)
    assert not (REPO / "-").exists() and not Path("-").exists()


def test_codegen_network_all_and_program(tmp_path, capsys):
    """--network all: one GLSL per network of an asset (prt_atrium has nine); --program: the whole pass with
    every include resolved, the vertex stage, and the uniforms and resources to bind, which glslang takes."""
    import json
    import shutil
    import subprocess

    from inshade.cli import main

    assert main(["-q", "codegen", "prt_atrium", "--network", "all", "--no-gl", "-o", str(tmp_path / "a.glsl")]) == 0
    glsl = sorted(p.name for p in tmp_path.glob("a.*.glsl"))
    assert len(glsl) == 9 and all("void region_" in (tmp_path / g).read_text() for g in glsl)
    assert main(["codegen", "prt_atrium", "--network", "all", "-o", "-", "--no-gl"]) == 2
    assert "-o -: 9 networks would share standard output" in capsys.readouterr().err
    assert main(["-q", "codegen", "prt_creature", "--program", "-o", str(tmp_path / "pass.frag")]) == 0
    frag, vert = (tmp_path / "pass.frag").read_text(), (tmp_path / "pass.vert").read_text()
    assert not any(line.lstrip().startswith("#include") for line in frag.splitlines())   # all resolved
    assert "void main()" in frag and "transfer_eval(" in frag
    manifest = json.loads((tmp_path / "pass.frag.json").read_text())
    assert manifest["vertex_shader"] == "pass.vert" and "u_inv_view_proj" in manifest["uniforms"]
    for path in (tmp_path / "pass.frag", tmp_path / "pass.vert"):
        proc = subprocess.run([shutil.which("glslangValidator"), str(path)], capture_output=True, text=True)
        assert proc.returncode == 0, proc.stdout[-2000:]
    assert vert


def test_generate_plans_with_the_machines_limits_when_asked(gl_limits):
    """GL 3.3's 16 KiB uniform block refuses a 64-wide layer; limits=machine_limits() takes this machine's, and
    the refusal says so."""
    from inshade.codegen import generate
    from inshade.codegen.limits import LimitError
    from inshade.models import mlp_graph

    bundle = mlp_graph(2, [64] * 3, 3).export("m")
    with pytest.raises(LimitError, match=r"GL 3\.3 minimum.*limits=machine_limits\(\)\) \(inshade\.runtime\.context\) plans with this machine's"):
        generate(bundle, storage="ubo")
    if gl_limits["GL_MAX_UNIFORM_BLOCK_SIZE"] >= 16640:
        from inshade.runtime.context import machine_limits

        g = generate(bundle, storage="ubo", limits=machine_limits())
        assert g.plan.limits["GL_MAX_UNIFORM_BLOCK_SIZE"]["source"] == "context"
