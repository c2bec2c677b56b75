"""scene/builder.py: the scene.json data writers build is what the parser reads, key for key."""
from __future__ import annotations

import json

import pytest

from inshade.scene import builder
from test_architecture import ROOT

TEXTURE_ASSET = ROOT / "trained" / "di_texture_chelsea"


def test_the_parts_are_the_fields_the_parser_reads():
    from inshade.scene.description import _KEYS

    built = builder.scene_json("x", "x", "passes/field2d.frag", (8, 8))
    assert set(built) | set(builder.PARTS) == _KEYS
    assert list(built) == ["format", "version", "name", "title", "program", "size"]


def test_parts_keep_the_order_they_are_given_in():
    built = builder.scene_json("x", "x", "p", (4, 2), requires=builder.requires(), camera=builder.plane2d())
    assert list(built)[-2:] == ["requires", "camera"] and built["size"] == [4, 2]


def test_unknown_parts_and_unbound_settings_are_refused():
    with pytest.raises(ValueError, match="^lamps: not a part of a scene"):
        builder.scene_json("x", "x", "p", (8, 8), lamps=[])
    with pytest.raises(ValueError, match="exactly one target"):
        builder.float_setting(1.0, 0.0, 2.0, "gain")
    with pytest.raises(ValueError, match="exactly one target"):
        builder.bool_setting(True, "on", uniform="u_on", define="ON")


def test_a_built_scene_is_the_shipped_file_and_parses():
    """di_texture's asset scene, built again from its own fields, is the shipped file byte for byte,
    and the parser reads it."""
    from inshade.scene.description import parse_scene
    from inshade.techniques.di_texture.train import scene_dict

    text = (TEXTURE_ASSET / "scene.json").read_text()
    shipped = json.loads(text)
    built = scene_dict(shipped["name"], shipped["title"], shipped["size"][0], shipped["networks"][0]["output"],
                       shipped["settings"]["lut_filter"]["default"])
    assert json.dumps(built, indent=2) + "\n" == text
    scene = parse_scene(built, root=TEXTURE_ASSET)
    assert scene.camera == builder.plane2d() and scene.reference is not None
    assert set(scene.settings) >= {"exposure", "error_scale", "lut_filter"}
