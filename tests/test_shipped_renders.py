"""Every shipped asset renders as the record says (tests/shipped_renders.py): bit-identical on the
renderer that made it (moving code between packages must not move a pixel), at >= 50 dB PSNR on
any other; each test says which comparison it made. The comparison itself is tested with a record
from another renderer.

Then the README's examples run as written: each `inshade render|codegen|info|convert` line of its
bash blocks, after its Python first-screen block (which makes `my_net`), in a scratch folder where
`trained/` is the shipped one and `model.onnx` a small ONNX file. Renders are the same commands at
48x48 (--width/--height appended): the programs, settings and files are what the README says, the
pixels few. They come last in this file: the record's renders have just compiled these programs
(the driver's shader cache keeps them), which spares minutes of llvmpipe JIT."""
from __future__ import annotations

import json
import re
import shlex
import warnings
from pathlib import Path

import numpy as np
import pytest

from shipped_renders import CASES, MADE_BY, MIN_PSNR_DB, RECORD, compare, key, render_case, renderer_of


@pytest.fixture(scope="module")
def record():
    with np.load(RECORD) as data:
        return {k: data[k] for k in data.files}


@pytest.fixture(scope="module")
def same_renderer():
    """Whether this process's renderer made the record; if not, the comparison says so once."""
    from inshade.runtime.context import shared_context

    recorded, here = json.loads(MADE_BY.read_text()), renderer_of(shared_context())
    if recorded != here:
        warnings.warn(f"shipped renders: the record was made by {recorded['gl_renderer']} "
                      f"({recorded['gl_version']}), this is {here['gl_renderer']} ({here['gl_version']}): "
                      f"compared at >= {MIN_PSNR_DB:.0f} dB PSNR instead of bit for bit")
    return recorded == here


def test_record_covers_every_case(record):
    assert sorted(record) == sorted(key(a, s) for a, s in CASES)


def test_record_says_which_renderer_made_it():
    made_by = json.loads(MADE_BY.read_text())
    assert set(made_by) == {"gl_renderer", "gl_version"} and all(made_by.values())


def test_same_renderer_means_bit_for_bit(record):
    want = record["sdf_creature"]
    assert compare("sdf_creature", want.copy(), want, same_renderer=True).startswith("bit-identical")
    one_ulp = want.copy()
    one_ulp[3, 5, 0] = np.nextafter(one_ulp[3, 5, 0], np.float32(2))
    with pytest.raises(AssertionError, match="1 values differ"):
        compare("sdf_creature", one_ulp, want, same_renderer=True)


def test_another_renderer_is_held_to_the_psnr_floor(record):
    """A record from another renderer: a driver's rounding (noise ~1e-4, ~80 dB) passes and says so;
    a broken program (a block of wrong pixels, ~30 dB) fails; a shape change fails."""
    want = record["sdf_creature"]
    rng = np.random.default_rng(0)
    rounded = (want + rng.normal(0, 1e-4, want.shape)).astype(np.float32)
    assert "another renderer" in compare("sdf_creature", rounded, want, same_renderer=False)
    broken = want.copy()
    broken[:8, :8] += 0.5
    with pytest.raises(AssertionError, match="under 50 dB"):
        compare("sdf_creature", broken, want, same_renderer=False)
    with pytest.raises(AssertionError, match="shape"):
        compare("sdf_creature", want[:-1], want, same_renderer=False)


@pytest.mark.parametrize("asset,settings", CASES, ids=[key(a, s) for a, s in CASES])
def test_shipped_asset_renders_as_recorded(gl, record, same_renderer, asset, settings):
    compare(key(asset, settings), render_case(asset, settings), record[key(asset, settings)], same_renderer)


# --- the README's examples ------------------------------------------------------------------

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()
COMMAND = re.compile(r"^(?:pip install -e \. && )?(inshade (?:render|codegen|info|convert)\b.*)$")


def readme_commands() -> list[str]:
    lines = []
    for block in re.findall(r"```bash\n(.*?)```", README, re.S):
        for line in block.splitlines():
            m = COMMAND.match(line.split(" #")[0].strip())
            if m:
                lines.append(m.group(1))
    return lines


def test_the_readme_has_examples_to_run():
    commands = readme_commands()
    assert len(commands) >= 10 and any(c.startswith("inshade convert") for c in commands)


def test_readme_examples_run(gl, tmp_path, monkeypatch, capsys):
    import numpy as np
    import onnx
    from onnx import TensorProto, helper, numpy_helper

    from inshade.cli import main

    monkeypatch.chdir(tmp_path)
    (tmp_path / "trained").symlink_to(ROOT / "trained")
    python = re.search(r"```python\n(.*?)```", README, re.S).group(1)
    exec(compile(python, "README.md", "exec"), {})                 # the first screen: makes my_net
    w = numpy_helper.from_array(np.random.default_rng(0).uniform(-1, 1, (3, 4)).astype(np.float32), "W")
    graph = helper.make_graph([helper.make_node("MatMul", ["x", "W"], ["h"]), helper.make_node("Relu", ["h"], ["y"])],
                              "g", [helper.make_tensor_value_info("x", TensorProto.FLOAT, ["N", 3])],
                              [helper.make_tensor_value_info("y", TensorProto.FLOAT, ["N", 4])], [w])
    onnx.save(helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)]), tmp_path / "model.onnx")
    from inshade.geometry import gltf_scenes

    gltf_scenes.tiles_torus().write(tmp_path / "model.glb")        # "Bring your model": a glTF file of our own
    failed = []
    for command in readme_commands():
        argv = shlex.split(command)[1:]
        if argv[0] == "render" and "--from" not in argv:
            argv += ["--width", "48", "--height", "48"]
        code = main(["-q", *argv])
        err = capsys.readouterr().err.strip().splitlines()
        if code != 0:
            failed.append(f"{command}: exit {code}: {err[-1:] }")
    assert not failed, "\n".join(failed)
    assert (tmp_path / "onnx_net" / "bundle.json").is_file() and (tmp_path / "my_net.glsl").is_file()
