"""The chunk resolver: includes, include-once, cycles, defines, headers, cache keys, line mapping."""

import re

import pytest

from inshade.shaders import (
    HEADER,
    LINE_STRIDE,
    ShaderIncludeError,
    assemble,
    explain_compile_error,
)


def body_lines(assembled):
    """Source lines that are neither preprocessor directives nor blank."""
    return [line for line in assembled.source.splitlines() if line.strip() and not line.lstrip().startswith("#")]


def test_includes_expand_recursively_in_order():
    chunks = {"main": "#include <a>\nint m;", "a": "  #  include   < b >  // why\nint a;", "b": "int b;"}
    assembled = assemble("main", chunks=chunks)
    assert body_lines(assembled) == ["int b;", "int a;", "int m;"]
    assert assembled.chunk_ids == {0: HEADER, 1: "main", 2: "a", 3: "b"}


def test_chunk_is_included_once():
    chunks = {"main": "#include <a>\n#include <b>\n#include <a>\nint m;", "a": "int a;", "b": "#include <a>\nint b;"}
    assert body_lines(assemble("main", chunks=chunks)) == [
        "int a;", "// #include <a>: already included", "int b;", "// #include <a>: already included", "int m;"]


def test_cycle_raises_with_chain():
    chunks = {"main": "#include <a>", "a": "#include <b>", "b": "#include <a>"}
    with pytest.raises(ShaderIncludeError, match=r"a -> b -> a"):
        assemble("main", chunks=chunks)


def test_self_include_is_a_cycle():
    with pytest.raises(ShaderIncludeError, match=r"a -> a"):
        assemble("a", chunks={"a": "#include <a>"})


def test_unknown_chunk_names_includer_and_line():
    chunks = {"main": "int x;\n\n#include <nope/missing>"}
    with pytest.raises(ShaderIncludeError, match=r"<nope/missing>.*main:3"):
        assemble("main", chunks=chunks)


def test_unknown_entry_raises():
    with pytest.raises(ShaderIncludeError, match="unknown chunk"):
        assemble("passes/does_not_exist.frag")


@pytest.mark.parametrize("name", ["../secret", "/etc/passwd", "a/../../b"])
def test_chunk_names_cannot_escape_the_library(name):
    with pytest.raises(ShaderIncludeError, match="invalid chunk name"):
        assemble(name)


def test_include_inside_if_is_rejected():
    chunks = {"main": "#ifdef X\n#include <a>\n#endif", "a": "int a;"}
    with pytest.raises(ShaderIncludeError, match=r"main:2.*inside #if"):
        assemble("main", chunks=chunks)


def test_version_in_chunk_is_rejected():
    with pytest.raises(ShaderIncludeError, match="#version"):
        assemble("main", chunks={"main": "#version 330 core\nvoid main(){}"})


def test_memory_chunks_override_files():
    assembled = assemble("main", chunks={"main": "#include <lib/colour>", "lib/colour": "int replaced;"})
    assert body_lines(assembled) == ["int replaced;"]
    assert assembled.chunk_paths["lib/colour"] is None


def test_file_chunks_resolve_from_library():
    assembled = assemble("passes/copy.frag")
    assert "uniform sampler2D u_source;" in assembled.source
    assert assembled.display_name("passes/copy.frag") == "shaders/passes/copy.frag.glsl"


def test_defines_sorted_typed_and_deterministic():
    defines = {"ZED": True, "ALPHA": 3, "OFF": False, "SCALE": 0.1, "ONE": 1.0, "TINY": 1e-10, "MODE": "vec3(1.0)"}
    first = assemble("main", defines=defines, chunks={"main": "int m;"})
    second = assemble("main", defines=dict(reversed(list(defines.items()))), chunks={"main": "int m;"})
    assert first.source == second.source and first.key == second.key
    lines = first.source.splitlines()
    assert lines[0] == "#version 330 core"
    assert lines[1:9] == [
        "#define ALPHA 3",
        "#define INSHADE_TARGET_330 1",
        "#define MODE vec3(1.0)",
        "#define OFF 0",
        "#define ONE 1.0",
        "#define SCALE 0.1",
        "#define TINY 1e-10",
        "#define ZED 1",
    ]


def test_float_defines_round_trip_float32():
    import numpy as np

    for value in np.random.default_rng(0).standard_normal(100).astype(np.float32):
        source = assemble("m", defines={"V": float(value)}, chunks={"m": ""}).source
        literal = re.search(r"^#define V (\S+)$", source, re.MULTILINE)[1]
        assert re.search(r"[.e]", literal)
        assert np.float32(float(literal)) == value


@pytest.mark.parametrize("bad", [{"1X": 1}, {"A B": 1}, {"X": float("nan")}, {"X": "a\nb"}, {"INSHADE_TARGET_330": 1}])
def test_bad_defines_rejected(bad):
    with pytest.raises((ValueError, TypeError)):
        assemble("m", defines=bad, chunks={"m": ""})


def test_target_headers():
    assert assemble("m", version="450", chunks={"m": ""}).source.startswith(
        "#version 450 core\n#define INSHADE_TARGET_450 1\n")
    es = assemble("m", version="es300", chunks={"m": ""}).source.splitlines()
    assert es[:5] == ["#version 300 es", "precision highp float;", "precision highp int;",
                      "precision highp sampler2D;", "precision highp sampler3D;"]
    assert "#define INSHADE_TARGET_ES300 1" in es
    with pytest.raises(ValueError):
        assemble("m", version="460", chunks={"m": ""})


def test_key_tracks_chunks_defines_and_version():
    base = assemble("m", chunks={"m": "#include <n>", "n": "int n;"})
    assert assemble("m", chunks={"m": "#include <n>", "n": "int n;"}).key == base.key
    assert assemble("m", chunks={"m": "#include <n>", "n": "int n2;"}).key != base.key
    assert assemble("m", defines={"A": 1}, chunks={"m": "#include <n>", "n": "int n;"}).key != base.key
    assert assemble("m", version="450", chunks={"m": "#include <n>", "n": "int n;"}).key != base.key
    assert set(base.chunk_hashes) == {"m", "n"}


def test_line_markers_and_locate_every_line():
    """Every line of the assembled source maps back to the chunk line it came from."""
    chunks = {"m": "int m1;\n#include <a>\nint m3;\n#include <b>\nint m5;", "a": "int a1;\n#include <b>\nint a3;",
              "b": "int b1;\nint b2;"}
    assembled = assemble("m", chunks=chunks)
    # Simulate a GLSL 3.30 preprocessor: "#line N S" numbers the next line N.
    line, source = 1, 0
    for text in assembled.source.splitlines():
        directive = re.match(r"#line (\d+) (\d+)", text)
        if directive:
            line, source = int(directive[1]), int(directive[2])
            continue
        if text.startswith("int "):
            chunk, chunk_line = assembled.locate(source, line)
            assert text == f"int {chunk}{chunk_line};"
            assert assembled.locate(0, line) == (chunk, chunk_line)  # Mesa may report source 0
        line += 1


def test_locate_header_lines():
    assembled = assemble("m", defines={"A": 1}, chunks={"m": ""})
    assert assembled.locate(0, 2) == (HEADER, 2)
    assert assembled.locate(1, LINE_STRIDE + 1) == ("m", 1)


@pytest.mark.parametrize("log, expected", [
    ("0:1000003(11): error: `x' undeclared\n0:1000003(6): error: cannot construct", ("m", 3, "error: `x' undeclared")),
    ("0:2(1): warning: meh\n1:1000002(1): error: syntax error", ("m", 2, "error: syntax error")),
    ("ERROR: 1:1000003: 'x' : undeclared identifier\nERROR: 1 compilation errors.", ("m", 3, "error: 'x' : undeclared identifier")),
    ("1(1000003) : error C1008: undefined variable \"x\"", ("m", 3, "error C1008: undefined variable \"x\"")),
])
def test_explain_driver_log_formats(log, expected):
    assembled = assemble("m", chunks={"m": "a\nb\nc"})
    error = explain_compile_error(assembled, log)
    assert (error.chunk, error.line, error.message) == expected
    assert str(error).startswith("<m>:")


def test_explain_without_location():
    error = explain_compile_error(assemble("m", chunks={"m": ""}), "error: linking failed\n")
    assert error.chunk is None and error.line is None and "linking failed" in error.message


def test_write_names_file_by_key_and_stage(tmp_path):
    assembled = assemble("passes/copy.frag")
    path = assembled.write(tmp_path)
    assert path.name == f"{assembled.key[:16]}.frag.glsl"
    assert path.read_text() == assembled.source


@pytest.mark.parametrize("version", ["330", "450", "es300"])
def test_library_chunks_pass_glslang(tmp_path, version):
    """Offline check of every target with the reference compiler (glslang-tools)."""
    import shutil
    import subprocess

    assert shutil.which("glslangValidator"), "glslangValidator not found on PATH: install glslang-tools"
    program = {"m.frag": "#include <lib/colour>\n#include <passes/copy.frag>"}
    for entry, stage in [("common/fullscreen.vert", "vert"), ("common/mesh.vert", "vert"), ("m.frag", "frag")]:
        path = assemble(entry, version=version, chunks=program).write(tmp_path, stage)
        result = subprocess.run(["glslangValidator", str(path)], capture_output=True, text=True)
        assert result.returncode == 0, result.stdout
