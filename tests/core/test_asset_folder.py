"""No trainer writes over an existing asset: without --out it writes a fresh ./inshade-out/<name>,
and a folder that already holds files (every shipped asset) is refused before any work unless
--force. A spy stops each run right after the folder is claimed, and the shipped assets are tried
through hard-linked copies, so a broken check can never let a test train into trained/."""
from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from inshade import asset_folder
from inshade.asset_folder import OutputExistsError, claim
from inshade.technique import techniques

ROOT = Path(__file__).resolve().parents[2]
TRAINED = ROOT / "trained"
TRAINERS = sorted(t.name for t in techniques() if t.train)
# The arguments argparse (and the checks before the folder) require of each trainer.
MINIMAL_ARGS = {
    "neural_image": [], "neural_sdf": [], "di_pbr_set": [], "di_footprint": [], "di_sdf": [],
    "di_shading": [], "di_radiance_field": [], "neural_appearance": [], "uvfree_material": [],
    "appearance_prefilter": [],
    "prt": ["--sdf", str(TRAINED / "sdf_creature" / "sdf.json")],
    "di_texture": ["skimage:astronaut"],
    "di_brdf": ["ggx"],
    "hash_grid": ["image"],
}
# A shipped asset each trainer builds (the folder a careless --out would name).
SHIPPED = {"neural_sdf": "prt_neural_bunny/sdf", "prt": "prt_creature", "di_texture": "di_texture_astronaut",
           "di_brdf": "di_brdf_ggx", "neural_appearance": "neural_appearance_ceramic",
           "uvfree_material": "uvfree_material_rock_balanced", "appearance_prefilter": "appearance_prefilter_grove",
           "di_pbr_set": "di_pbr_set_bricks", "di_shading": "di_shading_bricks",
           "di_radiance_field": "di_radiance_field_trinket", "hash_grid": "hash_grid_image"}


class Claimed(Exception):
    """Raised by the spy once a folder is granted: the run stops before any work."""


@pytest.fixture
def spy(monkeypatch):
    real = asset_folder.claim

    def stop_after_claim(*args, **kw):
        raise Claimed(real(*args, **kw))

    monkeypatch.setattr(asset_folder, "claim", stop_after_claim)


def _snapshot(folder: Path) -> dict:
    return {p: (p.stat().st_mtime_ns, p.stat().st_size) for p in folder.rglob("*")}


def test_every_trainer_is_in_the_tables():
    assert TRAINERS and set(TRAINERS) == set(MINIMAL_ARGS)
    for name in TRAINERS:
        assert (TRAINED / SHIPPED.get(name, name)).is_dir(), name


@pytest.mark.parametrize("name", TRAINERS)
def test_trainer_refuses_its_shipped_asset_without_force(name, spy, tmp_path, capsys):
    from inshade.cli import main

    target = tmp_path / Path(SHIPPED.get(name, name)).name
    shutil.copytree(TRAINED / SHIPPED.get(name, name), target, copy_function=os.link)
    before = _snapshot(target)
    code = main(["train", name, *MINIMAL_ARGS[name], "--out", str(target), "--device", "cpu"])
    lines = capsys.readouterr().err.splitlines()
    assert code == 2 and len(lines) == 1, lines
    assert lines[0].startswith(f"inshade: error: {target}: --out: already holds an asset") and "--force" in lines[0]
    assert _snapshot(target) == before


@pytest.mark.parametrize("name", TRAINERS)
def test_trainer_writes_a_fresh_folder_by_default_and_over_one_with_force(name, spy, tmp_path, monkeypatch):
    from inshade.cli import main

    monkeypatch.chdir(tmp_path)
    with pytest.raises(Claimed) as granted:
        main(["train", name, *MINIMAL_ARGS[name], "--device", "cpu"])
    folder = granted.value.args[0]
    assert folder.parent == Path("inshade-out") and folder.name.startswith(name), folder
    target = tmp_path / "mine"
    target.mkdir()
    (target / "notes.txt").write_text("the user's")
    with pytest.raises(Claimed) as granted:
        main(["train", name, *MINIMAL_ARGS[name], "--out", str(target), "--force", "--device", "cpu"])
    assert granted.value.args[0] == target


def test_claim_rules(tmp_path):
    assert claim(None, "x") == Path("inshade-out/x")
    assert claim(tmp_path / "new", "x") == tmp_path / "new"            # missing: created by the writer
    assert claim(tmp_path, "x") == tmp_path                            # empty
    (tmp_path / "checkpoint.safetensors").write_bytes(b"")
    assert claim(tmp_path, "x", resume=("checkpoint.safetensors",)) == tmp_path   # an unfinished run resumes
    with pytest.raises(OutputExistsError, match="already holds an asset .checkpoint.safetensors."):
        claim(tmp_path, "x")
    for i in range(4):
        (tmp_path / f"f{i}").write_text("")
    with pytest.raises(OutputExistsError, match=r"\(checkpoint.safetensors, f0, f1 and 2 more\)"):
        claim(tmp_path, "x")
    assert claim(tmp_path, "x", force=True) == tmp_path
    with pytest.raises(OutputExistsError, match="is a file"):
        claim(tmp_path / "f0", "x", force=True)
