"""Presets, not hidden recipes: every shipped asset records the preset that built it and
the settings that preset resolved to, and those settings are what the trainer's `--preset ship`
gives today -- so the docs' rebuild command (each technique's page, `inshade train NAME --preset ship ...`) rebuilds the
asset with the same recipe. A new asset without the fields fails here.

Each trainer exposes `preset_settings(preset, asset)` (asset: the folder name under trained/, for
trainers whose shipped assets differ in their inputs: image, material, object, BRDF, PRT recipe)."""
from __future__ import annotations

import importlib
import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TRAINED = ROOT / "trained"
# Techniques whose shipped assets this file checks (prefix of the folder name -> technique).
TECHNIQUES = ("neural_image", "di_texture", "di_pbr_set", "di_footprint", "di_brdf", "di_sdf",
              "neural_appearance", "uvfree_material", "appearance_prefilter", "di_shading",
              "di_radiance_field", "hash_grid", "prt")
# Folders built outside these trainers: sdf_* (hand-written analytic SDF scenes, no trainer).
ELSEWHERE = ("sdf",)
# Shipped folders a technique builds with another of its modules than its trainer (python -m ...).
BUILDERS = {"prt_atrium": "prt.regions_train", "prt_mesh_texture": "prt.texture_prt"}


def technique_of(folder: str) -> str:
    names = [t for t in TECHNIQUES + ELSEWHERE if folder == t or folder.startswith(t + "_")]
    assert names, f"trained/{folder}: no technique claims it (add it to tests/test_presets.py)"
    return max(names, key=len)


def trainer(technique: str):
    return importlib.import_module(f"inshade.techniques.{technique}.train")


def builder(folder: str):
    """The module that built the shipped folder: its technique's trainer, or the one BUILDERS names."""
    name = BUILDERS.get(folder)
    return importlib.import_module(f"inshade.techniques.{name}") if name else trainer(technique_of(folder))


SHIPPED = sorted(p.name for p in TRAINED.iterdir() if p.is_dir() and technique_of(p.name) in TECHNIQUES)


def test_every_technique_has_shipped_assets_checked():
    assert {technique_of(n) for n in SHIPPED} == set(TECHNIQUES)


@pytest.mark.parametrize("folder", SHIPPED)
def test_shipped_asset_records_the_ship_preset_and_its_settings(folder):
    path = TRAINED / folder / "metrics.json"
    assert path.is_file(), f"{path}: missing (the trainer writes it; it records preset and settings)"
    metrics = json.loads(path.read_text())
    assert metrics.get("preset") == "ship", f"{path}: preset {metrics.get('preset')!r}"
    assert "settings" in metrics, f"{path}: no 'settings'"
    ship = json.loads(json.dumps(builder(folder).preset_settings("ship", folder)))   # a tuple reads back as a list
    assert metrics["settings"] == ship, f"{path}: settings differ from what --preset ship resolves to"


def test_shipped_network_sdf_was_built_by_the_ship_preset():
    """neural_sdf ships inside trained/prt_neural_bunny/sdf: its bundle provenance holds the settings."""
    prov = json.loads((TRAINED / "prt_neural_bunny" / "sdf" / "bundle.json").read_text())["provenance"]
    ship = trainer("neural_sdf").preset_settings("ship")
    assert {k: prov[k] for k in ship} == ship


def test_presets_differ_and_explicit_options_win():
    """quick is not ship, and an explicit option overrides the preset (neural_sdf's resolver)."""
    import argparse

    ns = trainer("neural_sdf")
    assert ns.preset_settings("quick") != ns.preset_settings("ship")
    for t in TECHNIQUES:
        mod = trainer(t)
        assert set(mod.preset_settings("quick")) == set(mod.preset_settings("ship")), t
    brdf = trainer("di_brdf")
    args = brdf.add_arguments(argparse.ArgumentParser()).parse_args(["disney", "-o", "x"])
    assert args.preset == "ship" and args.steps is None      # filled from the preset in run()


def test_quick_preset_records_its_settings(tmp_path):
    """A quick run end to end (neural_sdf on the procedural rabbit, seconds): metrics.json holds the
    preset and exactly the settings preset_settings("quick") names; the bundle's provenance too."""
    ns = trainer("neural_sdf")
    out = tmp_path / "sdf"
    assert ns.main(["--preset", "quick", "--out", str(out)]) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["preset"] == "quick"
    assert metrics["settings"] == ns.preset_settings("quick")
    prov = json.loads((out / "bundle.json").read_text())["provenance"]
    assert prov["preset"] == "quick" and prov["steps"] == metrics["settings"]["steps"]
    # an explicit option is recorded as given, beside the preset's name
    again = tmp_path / "again"
    assert ns.main(["--preset", "quick", "--steps", "3", "--out", str(again)]) == 0
    m2 = json.loads((again / "metrics.json").read_text())
    assert m2["preset"] == "quick" and m2["settings"] == {**ns.preset_settings("quick"), "steps": 3}
