"""The technique plug-in contract (inshade/technique.py): the registry, the runtime naming no
technique, and a toy technique that lives only in tests/plugins/toy_rings and still trains,
renders and shows up in the CLI."""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from inshade import technique
from inshade.scene.description import SceneError, parse_scene

ROOT = Path(__file__).resolve().parents[1]
TOY = Path(__file__).resolve().parent / "plugins" / "toy_rings"
RUNTIME_DIRS = ("runtime", "scene", "viewer", "shaders", "codegen")


def _cli(*args, env_extra=None, cwd=None):
    env = dict(os.environ, **(env_extra or {}))
    return subprocess.run([sys.executable, "-m", "inshade.cli", *args], capture_output=True, text=True,
                          env=env, cwd=cwd, timeout=600)


def test_builtin_techniques_are_registered_once_with_their_programs():
    names = [t.name for t in technique.techniques()]
    assert names[:9] == ["neural_image", "sdf", "neural_sdf", "prt", "di_texture", "di_pbr_set", "di_footprint",
                         "di_brdf", "di_sdf"]
    for t in technique.techniques():
        for spec in t.programs:
            assert technique.program_spec(spec.program) == (t, spec)
        if t.shaders is not None:
            assert t.shaders.is_dir(), t.name
    assert technique.current_kind("transfer") == "prt"
    assert technique.current_kind("di_ggx") == "di_brdf_ggx"


def test_every_shipped_asset_is_drawn_by_a_registered_program():
    for scene_file in sorted((ROOT / "trained").glob("*/scene.json")):
        program = json.loads(scene_file.read_text())["program"]
        technique.program_spec(program)
        name = scene_file.parent.name   # one name everywhere: trained/<technique>_* (di_sdf uses sdf's pass)
        assert any(name == t.name or name.startswith(t.name + "_") for t in technique.techniques()), scene_file


def test_registering_a_program_or_kind_twice_is_an_error():
    with pytest.raises(technique.TechniqueError, match="already belongs to 'prt'"):
        technique.register(technique.Technique("dup", "x", programs=(technique.ProgramSpec("passes/sdf_prt.frag"),)))
    with pytest.raises(technique.TechniqueError, match="bundle kind 'prt' already belongs"):
        technique.register(technique.Technique("dup", "x", kinds=("prt",)))
    with pytest.raises(technique.TechniqueError, match="train_alias 'compress' already names 'di_texture'"):
        technique.register(technique.Technique("dup", "x", train="dup.train", train_alias="compress"))
    with pytest.raises(technique.TechniqueError, match="train_alias needs a trainer"):
        technique.Technique("dup", "x", train_alias="dup")
    with pytest.raises(technique.TechniqueError, match="geometry"):
        technique.ProgramSpec("passes/x.frag", geometry="voxels")
    assert "dup" not in [t.name for t in technique.techniques()]


def test_a_scene_whose_program_no_technique_draws_is_one_error(tmp_path):
    (tmp_path / "passes").mkdir()
    data = {"format": "inshade.scene", "version": 1, "name": "x", "program": "passes/display.frag",
            "networks": []}
    with pytest.raises(SceneError, match="no technique draws program 'passes/display.frag'"):
        parse_scene(data, root=tmp_path)


def test_runtime_names_no_technique():
    """The runtime, viewer, shader resolver, codegen and the CLI hold no technique name and import
    no technique module: they ask the registry (a trainer's top-level alias such as `compress`
    comes from its record). ("sdf" is also a geometry every runtime draws, and "hash_grid" the
    component that technique is built on, which codegen emits: neither is searched for as a word.)"""
    from inshade.components import COMPONENTS

    names = [t.name for t in technique.techniques() if t.name not in technique.GEOMETRIES and t.name not in COMPONENTS]
    pattern = re.compile(r"\b(" + "|".join(map(re.escape, names)) + r")\b")
    found = []
    for folder in RUNTIME_DIRS:
        cli = [ROOT / "inshade/cli.py", *sorted((ROOT / "inshade/commands").glob("*.py"))]   # the command line
        for path in [*sorted((ROOT / folder).rglob("*.py")), *(cli * (folder == "runtime"))]:
            text = path.read_text()
            found += [f"{path.relative_to(ROOT)}: {m}" for m in pattern.findall(text)]
            if "inshade.techniques" in text:
                found.append(f"{path.relative_to(ROOT)}: imports inshade.techniques")
        for path in sorted((ROOT / folder).rglob("*.glsl")):
            found += [f"{path.relative_to(ROOT)}: {m}" for m in pattern.findall(path.read_text())]
    assert not found, "technique names in the runtime:\n" + "\n".join(found)


def test_packaging_names_no_technique():
    """pyproject.toml and setup.py name no technique: setup.py finds every technique folder, so
    adding one needs no packaging edit."""
    names = [t.name for t in technique.techniques() if t.name not in technique.GEOMETRIES]
    pattern = re.compile(r"\b(" + "|".join(map(re.escape, names)) + r")\b")
    for name in ("pyproject.toml", "setup.py"):
        assert not pattern.findall((ROOT / name).read_text()), name
    from inshade.techniques import BUILTIN

    folders = {d.name for d in (ROOT / "techniques").iterdir() if (d / "__init__.py").is_file()}
    assert set(BUILTIN) == folders


def test_toy_technique_trains_renders_and_is_listed(tmp_path):
    """One folder, registered through INSHADE_TECHNIQUES: `inshade train --help` lists it,
    `inshade train toy_rings` writes its asset, `inshade render` draws it, and the pixels equal a
    numpy evaluation of the same network, palette and per-frame tint."""
    env = {"INSHADE_TECHNIQUES": str(TOY)}
    help_ = _cli("train", "--help", env_extra=env)
    assert help_.returncode == 0, help_.stderr
    listed = " ".join(help_.stdout.split())   # argparse wraps help text to the longest name's column
    assert "toy_rings" in listed and "a random 2 -> 3 sine network" in listed
    for t in ("neural_image", "prt", "di_texture"):
        assert t in listed
    assert "toy_rings" not in _cli("train", "--help").stdout   # only where it is registered
    alias = _cli("rings", "--help", env_extra=env)                # its record's train_alias
    assert alias.returncode == 0 and "--seed" in alias.stdout, alias.stderr

    asset = tmp_path / "toy"
    made = _cli("train", "toy_rings", "-o", str(asset), env_extra=env)
    assert made.returncode == 0, made.stderr
    shot = tmp_path / "toy.exr"
    drawn = _cli("render", str(asset), "-o", str(shot), "--set", "warmth=0.25", env_extra=env, cwd=tmp_path)
    assert drawn.returncode == 0, drawn.stderr
    from inshade.scene.image_io import read_exr

    image = np.asarray(read_exr(shot), np.float64)[..., :3]
    h, w = image.shape[:2]
    sys.path.insert(0, str(TOY.parent))
    try:
        from toy_rings import PALETTE
        from toy_rings.train import weights
    finally:
        sys.path.remove(str(TOY.parent))
    wts = {k: v.astype(np.float64) for k, v in weights(0).items()}
    v, u = np.meshgrid((np.arange(h)[::-1] + 0.5) / h, (np.arange(w) + 0.5) / w, indexing="ij")
    uv = np.stack([u, v], -1)
    y = np.sin(uv @ wts["l0.weight"].T + wts["l0.bias"])
    tint = np.array([1.0, 1.0 - 0.5 * 0.25, 1.0 - 0.25])
    want = (0.5 + 0.5 * y) * np.array(PALETTE) * tint
    assert np.abs(image - want).max() < 1e-5

    sidecar = json.loads(Path(str(shot) + ".json").read_text())
    assert sidecar["view"]["settings"]["warmth"] == 0.25
    unregistered = _cli("render", str(asset), "-o", str(tmp_path / "x.png"))
    assert unregistered.returncode == 2
    assert "no technique draws program 'passes/toy_rings.frag'" in unregistered.stderr
    assert "Traceback" not in unregistered.stderr
