"""The branches a GLSL preprocessor keeps, read without a driver (shaders/active.py): what the compile-
cost estimate counts. Checked against glslangValidator's own preprocessor (-E; Debian glslang-tools, a
test requirement as in .ci/run)."""
from __future__ import annotations

import shutil
import subprocess

import pytest

from inshade.shaders.active import Unevaluable, active_source, called, evaluate

SOURCE = """#version 450
#define NA_DECODER 32
#define MODE (2 * 3)
#define NET_EVAL dec32_eval
void dec16_eval(in vec4 x, out vec4 y) { y = x; }
void dec32_eval(in vec4 x, out vec4 y) { y = 2.0 * x; }
void unused_eval(in vec4 x, out vec4 y) { y = x; }
vec4 shade(vec4 x) {
    vec4 y;
#if NA_DECODER == 16
    dec16_eval(x, y);
#elif NA_DECODER == 32 && defined(MODE) && MODE >= 6
    NET_EVAL(x, y);
#else
    unused_eval(x, y);
#endif
#ifdef NOT_DEFINED
    unused_eval(x, y);
#endif
#ifndef NOT_DEFINED
    y += 1.0;
#endif
#if !defined NA_DECODER || (0x10 >> 4) != 1
    unused_eval(x, y);
#endif
    return y;
}
layout(location = 0) out vec4 colour;
void main() { colour = shade(vec4(1.0)); }
"""


def test_the_kept_branches_and_the_functions_they_call():
    text, macros = active_source(SOURCE)
    assert "NET_EVAL(x, y);" in text and "y += 1.0;" in text
    assert "dec16_eval(x, y);" not in text and "unused_eval(x, y);" not in text
    assert macros["NA_DECODER"] == "32" and macros["NET_EVAL"] == "dec32_eval"
    assert called(SOURCE, ["dec16_eval", "dec32_eval", "unused_eval"]) == {"dec32_eval"}


@pytest.mark.parametrize("expr, want", [("1 + 2 * 3", 7), ("A == 4 && !B", 1), ("defined(A) || C", 1),
                                        ("(A << 2) % 5", 1), ("UNDEFINED", 0), ("7 / 2", 3), ("0x1Fu", 31)])
def test_expressions(expr, want):
    assert evaluate(expr, {"A": "4", "B": "0"}) == want


@pytest.mark.parametrize("line", ["#if F(1)", "#if 1.5 > 1", "#define F(x) x"])
def test_what_it_does_not_read_is_said(line):
    with pytest.raises(Unevaluable):
        active_source(f"#define F 1\n{line}\n#endif\n")


def test_it_keeps_what_glslang_keeps(tmp_path):
    assert shutil.which("glslangValidator"), "glslangValidator not found on PATH: install glslang-tools"
    src = tmp_path / "a.frag"
    src.write_text(SOURCE)
    run = subprocess.run(["glslangValidator", "-E", str(src)], capture_output=True, text=True, check=True)
    # glslang -E respaces the tokens and expands the macros
    theirs = "".join(ln for ln in run.stdout.splitlines() if not ln.lstrip().startswith("#")).replace(" ", "")
    assert active_source(SOURCE)[0].replace("NET_EVAL", "dec32_eval").replace(" ", "").replace("\n", "") == theirs
