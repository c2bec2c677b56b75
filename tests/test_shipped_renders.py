"""Every shipped asset renders bit-identical to the record written before the technique plug-in
refactor (tests/shipped_renders.py): moving code between packages must not move a pixel.

Then the README's examples run as written: each `inshade render|codegen|info|convert` line of its
bash blocks, after its Python first-screen block (which makes `my_net`), in a scratch folder where
`trained/` is the shipped one and `model.onnx` a small ONNX file. Renders are the same commands at
48x48 (--width/--height appended): the programs, settings and files are what the README says, the
pixels few. They come last in this file: the record's renders have just compiled these programs
(the driver's shader cache keeps them), which spares minutes of llvmpipe JIT."""
from __future__ import annotations

import re
import shlex
from pathlib import Path

import numpy as np
import pytest

from shipped_renders import CASES, RECORD, key, render_case


@pytest.fixture(scope="module")
def record():
    with np.load(RECORD) as data:
        return {k: data[k] for k in data.files}


def test_record_covers_every_case(record):
    assert sorted(record) == sorted(key(a, s) for a, s in CASES)


@pytest.mark.parametrize("asset,settings", CASES, ids=[key(a, s) for a, s in CASES])
def test_shipped_asset_renders_bit_identical(gl, record, asset, settings):
    image = render_case(asset, settings)
    want = record[key(asset, settings)]
    assert image.shape == want.shape
    diff = np.abs(image.astype(np.float64) - want)
    assert np.array_equal(image, want), (f"{key(asset, settings)}: {int((diff > 0).sum())} values differ, "
                                         f"max {diff.max():.3g}")


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
