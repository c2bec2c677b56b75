"""A program's choices are declared once (inshade/technique.py ``Choice`` on ``ProgramSpec.choices``):
the runtime generates their ``#define``s as the chunk <choices>, checks a scene's choice settings
against them and sets the declared index. Checked here on a toy program (tests register it) and on
every registered program: the generated names are the declared ones, each pass that declares
choices includes <choices>, and no GLSL writes one of those names by hand."""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from inshade import technique
from inshade.bundle import Bundle
from inshade.scene.description import SceneError, load_scene
from inshade.technique import Choice, ProgramSpec, Technique, TechniqueError, choice_chunks

ROOT = Path(__file__).resolve().parents[2]
GLSL_ROOTS = [ROOT / "shaders", *sorted((ROOT / "techniques").glob("*/shaders"))]
_DEFINE = re.compile(r"^\s*#\s*define\s+([A-Za-z_][A-Za-z0-9_]*)", re.MULTILINE)

TOY_PROGRAM = "passes/choice_toy.frag"
TOY_CHOICES = (Choice("u_toy_view", "TOY_VIEW", ("near", "mid", "far")),
               Choice("TOY_MODE", "TOY_MODE", {"off": 0, "on": 3}))
TOY_PASS = """#include <network>
#include <choices>
uniform int u_toy_view;
layout(location = 0) out vec4 frag_color;
void main() {
    frag_color = vec4(float(u_toy_view), float(TOY_MODE), float(TOY_VIEW_FAR), float(TOY_MODE_ON));
}
"""


# the contract ---------------------------------------------------------------------------------------
def test_a_choice_is_a_table_of_names_and_indices():
    view = Choice("u_view", "VIEW", ("analytic", "learned", "split"))
    assert view.values == ("analytic", "learned", "split") and view.indices == (0, 1, 2)
    assert view.defines() == {"VIEW_ANALYTIC": 0, "VIEW_LEARNED": 1, "VIEW_SPLIT": 2}
    assert view.index("split") == 2
    model = Choice("MODEL", "MODEL", {"ggx": 1, "disney": 2})   # a mapping: indices with an offset
    assert model.defines() == {"MODEL_GGX": 1, "MODEL_DISNEY": 2} and model.index("disney") == 2
    chunk = choice_chunks(ProgramSpec("passes/x.frag", choices=(view, model)))
    assert _defines_of(chunk["choices"]) == {**view.defines(), **model.defines()}
    assert choice_chunks(ProgramSpec("passes/x.frag")) == {}


@pytest.mark.parametrize("args,message", [
    (("u_view", "view", ("a",)), "prefix must be an upper-case GLSL name"),
    (("u view", "VIEW", ("a",)), "target must be a uniform or define name"),
    (("u_view", "VIEW", ()), "needs at least one value"),
    (("u_view", "VIEW", ("close-up",)), "values must be lower-case identifiers"),
    (("u_view", "VIEW", "abc"), "values must be a sequence or a mapping"),
    (("u_view", "VIEW", {"a": 0, "b": 0}), "two values share an index"),
    (("u_view", "VIEW", {"a": -1}), "index must be an int >= 0"),
])
def test_a_bad_choice_is_refused_where_it_is_declared(args, message):
    with pytest.raises(TechniqueError, match=message):
        Choice(*args)


def test_a_program_declares_a_target_and_a_name_once():
    with pytest.raises(TechniqueError, match="two choices drive 'u_view'"):
        ProgramSpec("passes/x.frag", choices=(Choice("u_view", "A", ("x",)), Choice("u_view", "B", ("y",))))
    with pytest.raises(TechniqueError, match="two choices generate A_B_C"):
        ProgramSpec("passes/x.frag", choices=(Choice("u_a", "A", ("b_c",)), Choice("u_b", "A_B", ("c",))))
    with pytest.raises(TechniqueError, match="choices must be Choice records"):
        ProgramSpec("passes/x.frag", choices=(("u_view", "VIEW", ("x",)),))


# every registered program ---------------------------------------------------------------------------
def _declaring():
    return [(t, spec) for t in technique.techniques() for spec in t.programs if spec.choices]


def _defines_of(source: str) -> dict:
    return {name: int(value) for name, value in re.findall(r"^#define (\w+) (\d+)$", source, re.MULTILINE)}


def test_generated_defines_are_the_declared_values_of_every_program():
    for t, spec in _declaring():
        want = {f"{c.prefix}_{v.upper()}": i for c in spec.choices for v, i in zip(c.values, c.indices)}
        assert _defines_of(choice_chunks(spec)["choices"]) == want, spec.program
        source = (t.shaders / f"{spec.program}.glsl").read_text()
        assert "#include <choices>" in source, f"{spec.program} declares choices but does not include <choices>"


def test_no_glsl_writes_a_declared_choice_name_by_hand():
    declared = {name: spec.program for _, spec in _declaring() for c in spec.choices for name in c.defines()}
    found = []
    for root in GLSL_ROOTS:
        for path in sorted(root.rglob("*.glsl")):
            found += [f"{path.relative_to(ROOT)}: #define {name} (declared by {declared[name]})"
                      for name in _DEFINE.findall(path.read_text()) if name in declared]
    assert not found, "hand-written defines of declared choices:\n" + "\n".join(found)


def test_every_shipped_choice_setting_of_a_program_enumeration_is_declared():
    """A shipped scene's choice that sets a uniform, or names the values of a define, drives a
    declared choice (its index comes from the program, not from the scene's list)."""
    undeclared = []
    for folder in sorted((ROOT / "trained").glob("*/scene.json")):
        for name, s in load_scene(folder.parent).settings.items():
            named = s.binding == "define" and any(isinstance(c, str) for c in s.choices)
            if s.type == "choice" and (s.binding == "uniform" or named) and s.declared is None:
                undeclared.append(f"{folder.parent.name}: settings.{name} ({s.binding} {s.target})")
    assert not undeclared, "choice settings the program does not declare:\n" + "\n".join(undeclared)


# a toy program: scene checks and the bound index -----------------------------------------------------
@pytest.fixture
def toy(tmp_path):
    """A registered toy technique whose pass shows its choice uniform and defines, and a writer of
    its scene folder with the given settings."""
    shaders = tmp_path / "shaders" / "passes"
    shaders.mkdir(parents=True)
    (shaders / "choice_toy.frag.glsl").write_text(TOY_PASS)
    record = technique.register(Technique("choice_toy", "a test-only program with declared choices",
                                          programs=(ProgramSpec(TOY_PROGRAM, choices=TOY_CHOICES),),
                                          shaders=tmp_path / "shaders"))

    def write(settings: dict, name: str = "asset") -> Path:
        out = tmp_path / name
        meta = {"format": "inshade.bundle", "version": 1, "kind": "choice_toy", "name": name,
                "inputs": [{"name": "uv", "dim": 2, "semantic": "uv"}],
                "nodes": [{"id": "l0", "type": "dense", "inputs": ["uv"], "params": {"out": 3, "bias": True}}],
                "outputs": [{"name": "rgb", "node": "l0", "semantic": "linear_rgb"}]}
        Bundle(meta, {"l0.weight": np.zeros((3, 2), np.float32), "l0.bias": np.zeros(3, np.float32)}).save(out)
        scene = {"format": "inshade.scene", "version": 1, "name": name, "program": TOY_PROGRAM, "size": [4, 4],
                 "networks": [{"bundle": "."}], "camera": {"type": "plane2d"}, "settings": settings}
        (out / "scene.json").write_text(json.dumps(scene))
        return out

    yield write
    technique.unregister(record.name)


VIEW = {"type": "choice", "default": "far", "choices": ["far", "near"], "uniform": "u_toy_view"}
MODE = {"type": "choice", "default": "on", "choices": ["on", "off"], "define": "TOY_MODE"}


def test_a_scene_setting_naming_an_undeclared_value_is_one_error(toy):
    bad = dict(VIEW, choices=["far", "wide"])
    with pytest.raises(SceneError, match=r"settings\.view\.choices: 'wide' is not a u_toy_view value of "
                                         r"passes/choice_toy\.frag \(known: near, mid, far\)"):
        load_scene(toy({"view": bad, "mode": MODE}))
    with pytest.raises(SceneError, match=r"settings\.mode\.choices: 'auto' is not a TOY_MODE value"):
        load_scene(toy({"mode": dict(MODE, choices=["on", "auto"])}, "mode"))
    with pytest.raises(SceneError, match=r"settings\.mode: 1 is not a TOY_MODE index"):
        load_scene(toy({"mode": {"type": "int", "default": 0, "min": 0, "max": 3, "define": "TOY_MODE"}}, "range"))
    with pytest.raises(SceneError, match=r"settings\.view\.type: u_toy_view is a choice of passes/choice_toy\.frag"):
        load_scene(toy({"view": {"type": "float", "default": 0.0, "min": 0.0, "max": 1.0, "uniform": "u_toy_view"}},
                       "float"))


def test_declared_settings_take_any_subset_in_any_order(toy):
    scene = load_scene(toy({"view": VIEW, "mode": MODE,
                            "index_form": {"type": "choice", "default": 3, "choices": [0, 3], "define": "TOY_MODE"}}))
    view, mode = scene.settings["view"], scene.settings["mode"]
    assert view.declared is TOY_CHOICES[0] and mode.declared is TOY_CHOICES[1]
    assert [view.index(v) for v in view.choices] == [2, 0] and [mode.index(v) for v in mode.choices] == [3, 0]
    assert scene.settings["index_form"].index(3) == 3


def test_the_program_gets_the_declared_index_and_the_generated_names(gl, toy):
    from inshade.runtime.render import read_rgba_raw
    from inshade.runtime.renderer import SceneRenderer

    scene = load_scene(toy({"view": VIEW, "mode": MODE}))
    for values, want in (({}, (2, 3, 2, 3)), ({"view": "near", "mode": "off"}, (0, 0, 2, 3))):
        r = SceneRenderer(scene, gl, settings=values)
        try:
            fbo = r.render_network(scene.make_camera(), 4, 4)
            np.testing.assert_array_equal(read_rgba_raw(fbo)[0, 0], np.float32(want), err_msg=str(values))
            assert "#define TOY_VIEW_MID 1" in r.assembled()["fragment"]
        finally:
            r.release()
