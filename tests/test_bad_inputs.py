"""Corpus of malformed inputs: every one is refused by the CLI with one line and exit status 2.

Each case builds a bad input in a fresh folder, runs ``python -m inshade.cli -q ...`` in a process
of its own (see below) and checks the project rule (README, "Nothing silent, nothing partial"):

* exit status 2;
* stderr is exactly one line, starting with ``inshade: error:`` and naming the file or field;
* no ``Traceback``;
* no output file left behind (the output folder is listed before and after: no temporary file
  either), and an output that existed before is untouched;
* memory: the child runs under ``RLIMIT_AS`` = 4 GiB of address space (MEMORY_LIMIT), so input
  that makes the loader allocate what a file merely claims (a 1e12-element tensor) fails as a
  MemoryError traceback instead of passing.

How cases run: a ``python -m inshade.cli`` process spends ~1.3 s of its ~1.5 s importing (numpy,
scipy, trimesh, moderngl, Pillow, the technique records). So the module fixture starts one fork
server (tests/bad_input_worker.py, with the environment such a subprocess would have) that imports
those modules once (modules only: no GL context, no thread, no torch), then forks one child per
case, JOBS at a time. The child sets ``RLIMIT_AS``, changes to the case folder, sends fds 1 and 2 to
files (fd 0 from /dev/null), and runs ``runpy.run_module("inshade.cli", run_name="__main__",
alter_sys=True)`` as ``python -m`` does, at the server script's top level, so the interpreter
itself ends it (SystemExit's status; an uncaught exception's traceback and status 1; atexit,
flushes, finalization). A child still running after TIMEOUT is killed. A child costs ~0.13 s of
CPU instead of ~1.5 s: the corpus ~20 s of CPU instead of ~210 s (~10 s on 2 idle cores). ``test_child_is_a_limited_interpreter`` runs control scripts
through the same server (an 8 GiB allocation must end as a MemoryError traceback, a raise as a
traceback with status 1, statuses and output pass through, the limit/folder/argv are the case's,
a sleeper is killed at its timeout); ``test_fork_server_answers_as_python_m`` runs one case again
as a real ``python -m inshade.cli`` subprocess and compares status, stdout and stderr.

Cases are grouped by class; the test id is ``CLASS(N)-case`` with N the size of the class.
"""
from __future__ import annotations

import json
import os
import resource
import shutil
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
SOURCE = REPO / "trained" / "neural_image"     # small valid bundle + scene (bundle has a "render" field)
MEMORY_LIMIT = 4 << 30                          # RLIMIT_AS of every child, bytes
SENTINEL = b"pre-existing output, must stay as it is\n"


# --- builders --------------------------------------------------------------------------------------
def _bundle(tmp: Path, name: str = "b") -> Path:
    folder = tmp / name
    folder.mkdir()
    for f in ("bundle.json", "weights.safetensors"):
        shutil.copy(SOURCE / f, folder / f)
    return folder


def _scene(tmp: Path) -> Path:
    folder = tmp / "s"
    shutil.copytree(SOURCE, folder, ignore=shutil.ignore_patterns("preview.png"))
    return folder


def _edit_json(path: Path, edit) -> None:
    data = json.loads(path.read_text())
    edit(data)
    path.write_text(json.dumps(data))


def _safetensors(header: dict, data: bytes = b"") -> bytes:
    raw = json.dumps(header).encode()
    return len(raw).to_bytes(8, "little") + raw + data


def _png_chunk(kind: bytes, body: bytes) -> bytes:
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))


def _png_claiming(width: int, height: int) -> bytes:
    """A PNG whose header claims width x height RGB pixels (with one tiny IDAT)."""
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", ihdr) + _png_chunk(b"IDAT", zlib.compress(b"\0\0\0\0"))
            + _png_chunk(b"IEND", b""))


CASES: dict[str, dict] = {}   # class -> {case: builder(tmp) -> (argv, expected substring, outputs)}


def case(cls: str, name: str):
    def register(fn):
        CASES.setdefault(cls, {})[name] = fn
        return fn
    return register


# bundle.json --------------------------------------------------------------------------------------
def _bundle_json_bytes(name, data: bytes):
    @case("bundle_json", name)
    def build(tmp):
        b = _bundle(tmp)
        (b / "bundle.json").write_bytes(data)
        return ["info", str(b)], "bundle.json", []


_bundle_json_bytes("empty", b"")
_bundle_json_bytes("whitespace_only", b"  \n\t ")
_bundle_json_bytes("bom", b"\xef\xbb\xbf" + (SOURCE / "bundle.json").read_bytes())
_bundle_json_bytes("not_utf8", b'{"format": "inshade.bundle", "name": "\xff\xfe"}')
_bundle_json_bytes("utf16", (SOURCE / "bundle.json").read_text().encode("utf-16"))
_bundle_json_bytes("nan_literal", b'{"format": "inshade.bundle", "version": NaN}')
_bundle_json_bytes("infinity_literal", b'{"format": "inshade.bundle", "version": 1, "x": -Infinity}')
_bundle_json_bytes("float_overflow", b'{"format": "inshade.bundle", "version": 1e400}')
_bundle_json_bytes("int_5000_digits", b'{"format": "inshade.bundle", "version": ' + b"9" * 5000 + b"}")
_bundle_json_bytes("deep_nesting", b'{"provenance": ' + b"[" * 100000 + b"]" * 100000 + b"}")
_bundle_json_bytes("deep_nesting_unclosed", b"[" * 1000000)
_bundle_json_bytes("truncated", (SOURCE / "bundle.json").read_bytes()[:200])
_bundle_json_bytes("top_level_list", b"[1, 2, 3]")
_bundle_json_bytes("png_named_json", _png_claiming(4, 4))


def _bundle_meta(name, edit, expect="bundle.json"):
    @case("bundle_json", name)
    def build(tmp):
        b = _bundle(tmp)
        _edit_json(b / "bundle.json", edit)
        return ["info", str(b)], expect, []


def _dup_kind(tmp):
    b = _bundle(tmp)
    text = (b / "bundle.json").read_text().replace('"kind": "neural_image"',
                                                   '"kind": "neural_image", "kind": "other_kind"', 1)
    (b / "bundle.json").write_text(text)
    return ["info", str(b)], "appears twice", []


case("bundle_json", "duplicate_key")(_dup_kind)
_bundle_meta("version_2", lambda m: m.update(version=2), "version")
_bundle_meta("version_bool", lambda m: m.update(version=True), "version")
_bundle_meta("input_dim_1e12", lambda m: m["inputs"][0].update(dim=10 ** 12), "inputs[0].dim")
_bundle_meta("dense_out_1e12", lambda m: m["nodes"][1]["params"].update(out=10 ** 12), "nodes[1].params")
_bundle_meta("node_type_list", lambda m: m["nodes"][0].update(type=["dense"]), "nodes[0].type")
_bundle_meta("unknown_field", lambda m: m.update(extra=1), "extra")
_bundle_meta("inputs_not_list", lambda m: m.update(inputs={"uv": 2}), "inputs")


def _bundle_file_is_a_folder(cls, name, file):
    """A bundle whose ``file`` is a folder: the error names the file."""
    @case(cls, name)
    def build(tmp):
        b = _bundle(tmp)
        (b / file).unlink()
        (b / file).mkdir()
        return ["info", str(b)], file, []


_bundle_file_is_a_folder("bundle_json", "bundle_json_is_a_folder", "bundle.json")


@case("bundle_json", "bundle_folder_missing")
def _(tmp):
    return ["info", str(tmp / "nope")], "nope", []


# weights.safetensors ------------------------------------------------------------------------------
def _weights(name, make, expect="weights.safetensors"):
    @case("weights", name)
    def build(tmp):
        b = _bundle(tmp)
        w = b / "weights.safetensors"
        w.write_bytes(make(w.read_bytes()))
        return ["info", str(b)], expect, []


def _header_of(data: bytes) -> tuple[dict, bytes]:
    n = int.from_bytes(data[:8], "little")
    return json.loads(data[8:8 + n]), data[8 + n:]


def _with_header(edit):
    def make(data):
        header, body = _header_of(data)
        edit(header)
        return _safetensors(header, body)
    return make


_weights("empty", lambda d: b"")
_weights("seven_bytes", lambda d: d[:7])
_weights("truncated_half", lambda d: d[: len(d) // 2])
_weights("truncated_last_byte", lambda d: d[:-1])
_weights("trailing_garbage", lambda d: d + b"\0" * 64)
_weights("is_json_text", lambda d: (SOURCE / "bundle.json").read_bytes())
_weights("is_png", lambda d: _png_claiming(4, 4))
_weights("header_len_huge", lambda d: (1 << 62).to_bytes(8, "little") + d[8:])
_weights("header_not_object", lambda d: _safetensors([1, 2]))
_weights("header_bad_json", lambda d: (20).to_bytes(8, "little") + b"{not json at all....")
_weights("header_duplicate_key", lambda d: (lambda raw: len(raw).to_bytes(8, "little") + raw)(
    b'{"l0.bias": {"dtype": "F32", "shape": [1], "data_offsets": [0, 4]}, '
    b'"l0.bias": {"dtype": "F32", "shape": [1], "data_offsets": [0, 4]}}') + b"\0" * 4)
_weights("header_nan", lambda d: (lambda raw: len(raw).to_bytes(8, "little") + raw)(
    b'{"l0.bias": {"dtype": "F32", "shape": [NaN], "data_offsets": [0, 4]}}') + b"\0" * 4)
_weights("tensor_1e12_elements", _with_header(lambda h: h["l0.weight"].update(
    shape=[10 ** 6, 10 ** 6], data_offsets=[0, 4 * 10 ** 12])), "l0.weight")
_weights("tensor_2e9_elements_within_offsets", _with_header(lambda h: h["l0.weight"].update(
    shape=[1 << 31])), "l0.weight")
_weights("negative_shape", _with_header(lambda h: h["l0.bias"].update(shape=[-64])), "l0.bias")
_weights("bool_shape", _with_header(lambda h: h["l0.bias"].update(shape=[True])), "l0.bias")
_weights("unknown_dtype", _with_header(lambda h: h["l0.bias"].update(dtype="F8_E4M3")), "l0.bias")
_weights("offsets_reversed", _with_header(lambda h: h["l0.bias"].update(
    data_offsets=h["l0.bias"]["data_offsets"][::-1])), "l0.bias")
_weights("offsets_overlap", _with_header(lambda h: h["l0.bias"].update(
    data_offsets=h["l0.weight"]["data_offsets"][:1] + [h["l0.weight"]["data_offsets"][0] + 256])))
_weights("extra_header_field", _with_header(lambda h: h["l0.bias"].update(layout="nchw")), "l0.bias")
_weights("metadata_not_strings", _with_header(lambda h: h.update(__metadata__={"format": 1})), "__metadata__")


def _save_tensors(name, edit, expect):
    @case("weights", name)
    def build(tmp):
        from safetensors.numpy import load_file, save_file

        b = _bundle(tmp)
        tensors = load_file(str(b / "weights.safetensors"))
        edit(tensors)
        save_file(tensors, str(b / "weights.safetensors"))
        return ["info", str(b)], expect, []


_save_tensors("nan_weight", lambda t: t["l0.weight"].reshape(-1).__setitem__(0, np.nan), "l0.weight")
_save_tensors("float64_weight", lambda t: t.update({"l1.bias": t["l1.bias"].astype(np.float64)}), "l1.bias")
_save_tensors("int8_weight", lambda t: t.update({"l1.bias": t["l1.bias"].astype(np.int8)}), "l1.bias")
_save_tensors("missing_tensor", lambda t: t.pop("l2.bias"), "l2.bias")
_save_tensors("extra_tensor", lambda t: t.update({"zz.weight": np.zeros(3, np.float32)}), "zz.weight")
_save_tensors("transposed", lambda t: t.update({"l0.weight": t["l0.weight"].T.copy()}), "l0.weight")


_bundle_file_is_a_folder("weights", "weights_is_a_folder", "weights.safetensors")


# scene.json (render: the scene is read before any GL context or output) --------------------------
def _render_scene(tmp, folder):
    out = tmp / "out" / "shot.png"
    return ["render", str(folder), "-o", str(out)], out


def _scene_bytes(name, make):
    @case("scene", name)
    def build(tmp):
        s = _scene(tmp)
        (s / "scene.json").write_bytes(make((s / "scene.json").read_bytes()))
        argv, out = _render_scene(tmp, s)
        return argv, "scene.json", [out]


_scene_bytes("empty", lambda d: b"")
_scene_bytes("bom", lambda d: b"\xef\xbb\xbf" + d)
_scene_bytes("not_utf8", lambda d: d.replace(b"neural_image", b"neural_\xe9mage", 1))
_scene_bytes("nan", lambda d: d.replace(b'"split": 0.5', b'"split": NaN', 1))
_scene_bytes("huge_number", lambda d: d.replace(b'"split": 0.5', b'"split": 1e999', 1))
_scene_bytes("duplicate_key", lambda d: d.replace(b'"version": 1,', b'"version": 1, "version": 1,', 1))
_scene_bytes("deep_nesting", lambda d: d.replace(b'"lights": []', b'"lights": ' + b"[" * 50000 + b"]" * 50000, 1))
_scene_bytes("truncated", lambda d: d[:100])
_scene_bytes("binary", lambda d: bytes(range(256)))


def _scene_json_edit(area, make_scene):
    """A case maker: ``make_scene(tmp)``'s scene.json edited by ``edit``, rendered, must fail naming ``expect``."""
    def add(name, edit, expect):
        @case(area, name)
        def build(tmp):
            s = make_scene(tmp)
            _edit_json(s / "scene.json", edit)
            argv, out = _render_scene(tmp, s)
            return argv, expect, [out]
    return add


_scene_edit = _scene_json_edit("scene", _scene)


_scene_edit("size_zero", lambda d: d.update(size=[0, 0]), "size")
_scene_edit("size_1e12", lambda d: d.update(size=[10 ** 12, 1]), "size")
_scene_edit("camera_type_list", lambda d: d["camera"].update(type=[]), "camera")
_scene_edit("camera_not_object", lambda d: d.update(camera="plane2d"), "camera")
_scene_edit("bookmark_type_list", lambda d: d["bookmarks"]["face"].update(type=[]), "bookmarks.face")
_scene_edit("display_modes_null", lambda d: d["display"].update(modes=None), "display.modes")
_scene_edit("choices_number", lambda d: d["settings"]["storage"].update(choices=5), "settings.storage.choices")
_scene_edit("network_bundle_missing", lambda d: d["networks"][0].update(bundle="nowhere"), "networks[0].bundle")
_scene_edit("version_string", lambda d: d.update(version="1"), "version")


@case("scene", "spp_on_a_deterministic_program")
def _(tmp):
    s = _scene(tmp)
    argv, out = _render_scene(tmp, s)
    return [*argv, "--spp", "4"], "spp 4: program passes/field2d.frag", [out]


@case("scene", "scene_json_is_a_folder")
def _(tmp):
    s = _scene(tmp)
    (s / "scene.json").unlink()
    (s / "scene.json").mkdir()
    argv, out = _render_scene(tmp, s / "scene.json")
    return argv, "scene.json", [out]


# screenshot sidecars (render --from) --------------------------------------------------------------
def _sidecar(name, make, expect="shot.png.json"):
    @case("sidecar", name)
    def build(tmp):
        s = _scene(tmp)
        good = {"scene": {"path": str(s)}, "view": {"camera": {"type": "plane2d"}, "settings": {}},
                "render": {"width": 8, "height": 8}, "bundles": []}
        side = tmp / "shot.png.json"
        data = make(good)
        side.write_bytes(data if isinstance(data, bytes) else json.dumps(data).encode())
        out = tmp / "out" / "re.png"
        return ["render", "--from", str(side), "-o", str(out)], expect, [out]


_sidecar("empty", lambda g: b"")
_sidecar("top_level_list", lambda g: [g])
_sidecar("no_scene_path", lambda g: {**g, "scene": {}})
_sidecar("scene_path_number", lambda g: {**g, "scene": {"path": 5}})
_sidecar("camera_type_list", lambda g: {**g, "view": {"camera": {"type": []}}})
_sidecar("render_not_object", lambda g: {**g, "render": [8, 8]})
_sidecar("width_1e12", lambda g: {**g, "render": {"width": 10 ** 12, "height": 8}}, "render.width")
_sidecar("nan", lambda g: json.dumps(g).replace('"width": 8', '"width": NaN').encode())
_sidecar("scene_gone", lambda g: {**g, "scene": {"path": "/nonexistent/scene"}}, "/nonexistent/scene")
_sidecar("spp_zero", lambda g: {**g, "spp": 0}, "spp: must be an int >= 1")
_sidecar("spp_string", lambda g: {**g, "spp": "4"}, "spp: must be an int >= 1")


# reference / texture images ----------------------------------------------------------------------
def _reference(name, make, edit=None):
    @case("images", name)
    def build(tmp):
        s = _scene(tmp)
        make(s)
        if edit:
            _edit_json(s / "scene.json", edit)
        argv, out = _render_scene(tmp, s)
        return argv, "reference", [out]


_reference("png_is_text", lambda s: (s / "reference.png").write_text("not a picture\n"))
_reference("png_is_empty", lambda s: (s / "reference.png").write_bytes(b""))
_reference("png_truncated", lambda s: (s / "reference.png").write_bytes((s / "reference.png").read_bytes()[:40]))
_reference("png_bad_crc", lambda s: (s / "reference.png").write_bytes(
    (lambda d: d[:29] + bytes([d[29] ^ 0xFF]) + d[30:])((s / "reference.png").read_bytes())))
_reference("png_claims_100000_square", lambda s: (s / "reference.png").write_bytes(_png_claiming(100000, 100000)))
_reference("png_claims_20000x1", lambda s: (s / "reference.png").write_bytes(_png_claiming(20000, 1)))
_reference("is_a_folder", lambda s: ((s / "reference.png").unlink(), (s / "reference.png").mkdir()))
_reference("linear_but_png", lambda s: None, lambda d: d["reference"].update(colour="linear"))
_reference("exr_is_text", lambda s: (s / "ref.exr").write_text("exr?"),
           lambda d: d["reference"].update(image="ref.exr", colour="linear"))


@case("images", "bundle_reference_png_is_text")
def _(tmp):
    b = _bundle(tmp)
    (b / "reference.png").write_text("not a picture\n")
    out = tmp / "out" / "shot.png"
    return ["render", str(b), "-o", str(out)], "reference", [out]


def _texture(name, make):
    @case("images", name)
    def build(tmp):
        s = _scene(tmp)
        make(s / "tex.png")
        _edit_json(s / "scene.json", lambda d: d.update(textures=[{"uniform": "u_tex", "image": "tex.png"}]))
        argv, out = _render_scene(tmp, s)
        return argv, "textures[0].image", [out]


_texture("texture_is_json", lambda p: p.write_text('{"not": "an image"}'))
_texture("texture_truncated", lambda p: p.write_bytes((SOURCE / "reference.png").read_bytes()[:100]))
_texture("texture_claims_huge", lambda p: p.write_bytes(_png_claiming(1 << 20, 1 << 20)))


# command-line options ----------------------------------------------------------------------------
def _cli(name, argv_of, expect):
    @case("options", name)
    def build(tmp):
        b = _bundle(tmp)
        out = tmp / "out" / "x"
        return [a.format(b=b, out=out) for a in argv_of], expect, [Path(str(out) + s) for s in
                                                                ("", ".png", ".glsl", ".png.json", ".glsl.json")]


_cli("no_command", [], "COMMAND")
_cli("unknown_command", ["frobnicate"], "frobnicate")
_cli("codegen_target_460", ["codegen", "{b}", "--no-gl", "--target", "460"], "--target")
_cli("codegen_storage_bogus", ["codegen", "{b}", "--no-gl", "--storage", "bogus"], "--storage")
_cli("codegen_no_bundle", ["codegen"], "bundle")
_cli("codegen_unknown_option", ["codegen", "{b}", "--no-gl", "--frobnicate"], "--frobnicate")
_cli("render_width_text", ["render", "{b}", "--width", "wide", "-o", "{out}.png"], "--width")
_cli("render_width_zero", ["render", "{b}", "--width", "0", "-o", "{out}.png"], "--width")
_cli("render_height_negative", ["render", "{b}", "--height", "-5", "-o", "{out}.png"], "--height")
_cli("render_height_huge", ["render", "{b}", "--height", "99999999999999999999", "-o", "{out}.png"], "--height")
_cli("render_no_output", ["render", "{b}"], "-o")
_cli("render_bad_suffix", ["render", "{b}", "-o", "{out}.bmp"], ".bmp")
_cli("render_set_no_equals", ["render", "{b}", "--set", "exposure", "-o", "{out}.png"], "--set")
_cli("render_set_twice", ["render", "{b}", "--set", "storage=ubo", "--set", "storage=inline", "-o", "{out}.png"],
     "storage")
_cli("render_storage_and_set", ["render", "{b}", "--storage", "ubo", "--set", "storage=inline", "-o", "{out}.png"],
     "storage")
_cli("info_missing_path", ["info", "{out}-nothing"], "nothing")
_cli("view_width_text", ["view", "{b}", "--width", "x"], "--width")


# output paths --------------------------------------------------------------------------------------
def _output(name, command, make_out, expect=None):
    @case("outputs", name)
    def build(tmp):
        b = _bundle(tmp)
        out, existing = make_out(tmp)
        argv = (["codegen", str(b), "--no-gl", "-o", str(out)] if command == "codegen"
                else ["render", str(b), "-o", str(out)])
        return argv, expect or str(out), [out, Path(str(out) + ".json")], existing
    return build


def _parent_is_file(suffix):
    def make(tmp):
        (tmp / "somefile.txt").write_text("a file\n")
        return tmp / "somefile.txt" / f"shot{suffix}", []
    return make


def _grandparent_is_file(suffix):
    def make(tmp):
        (tmp / "somefile.txt").write_text("a file\n")
        return tmp / "somefile.txt" / "deeper" / f"shot{suffix}", []
    return make


def _is_folder(suffix):
    def make(tmp):
        (tmp / f"dir{suffix}").mkdir()
        return tmp / f"dir{suffix}", []
    return make


_output("render_proc", "render", lambda tmp: (Path("/proc/inshade_bad_inputs.png"), []))
_output("codegen_proc", "codegen", lambda tmp: (Path("/proc/inshade_bad_inputs.glsl"), []))
_output("render_parent_is_file", "render", _parent_is_file(".png"), "somefile.txt")
_output("codegen_parent_is_file", "codegen", _parent_is_file(".glsl"), "somefile.txt")
_output("render_grandparent_is_file", "render", _grandparent_is_file(".png"), "somefile.txt")
_output("codegen_grandparent_is_file", "codegen", _grandparent_is_file(".glsl"), "somefile.txt")
_output("render_output_is_folder", "render", _is_folder(".png"), "dir.png")
_output("codegen_output_is_folder", "codegen", _is_folder(".glsl"), "dir.glsl")


@case("outputs", "render_sidecar_path_is_folder")
def _(tmp):
    b = _bundle(tmp)
    out = tmp / "out" / "shot.png"
    (tmp / "out" / "shot.png.json").mkdir(parents=True)
    return ["render", str(b), "-o", str(out)], "shot.png.json", [out]


@case("outputs", "existing_output_untouched_bad_bundle")
def _(tmp):
    b = _bundle(tmp)
    (b / "weights.safetensors").write_bytes(b"junk")
    out = tmp / "out" / "net.glsl"
    out.parent.mkdir()
    for p in (out, Path(str(out) + ".json"), out.with_suffix(".resources.safetensors")):
        p.write_bytes(SENTINEL)
    return (["codegen", str(b), "--no-gl", "-o", str(out), "--force"], "weights.safetensors", [],
            [out, Path(str(out) + ".json"), out.with_suffix(".resources.safetensors")])


@case("outputs", "existing_codegen_output_kept_without_force")
def _(tmp):
    b = _bundle(tmp)
    out = tmp / "out" / "net.glsl"
    out.parent.mkdir()
    out.write_bytes(SENTINEL)
    return ["codegen", str(b), "--no-gl", "-o", str(out)], "exists; add --force", [], [out]


@case("outputs", "existing_render_untouched_bad_scene")
def _(tmp):
    s = _scene(tmp)
    (s / "reference.png").write_text("text")
    out = tmp / "out" / "shot.png"
    out.parent.mkdir()
    out.write_bytes(SENTINEL)
    Path(str(out) + ".json").write_bytes(SENTINEL)
    return ["render", str(s), "-o", str(out)], "reference", [], [out, Path(str(out) + ".json")]


# sizes (these start a GL context: the limits are the context's) ---------------------------------
@case("sizes", "cli_16384_square")
def _(tmp):
    b = _bundle(tmp)
    out = tmp / "out" / "big.png"
    return ["render", str(b), "--width", "16384", "--height", "16384", "-o", str(out)], "16384x16384", [out]


@case("sizes", "cli_over_max")
def _(tmp):
    b = _bundle(tmp)
    out = tmp / "out" / "big.png"
    return ["render", str(b), "--width", "16385", "-o", str(out)], "--width", [out]


@case("sizes", "scene_size_16384")
def _(tmp):
    s = _scene(tmp)
    _edit_json(s / "scene.json", lambda d: d.update(size=[16384, 16384]))
    argv, out = _render_scene(tmp, s)
    return argv, "16384x16384", [out]


@case("sizes", "bundle_render_field_16384")
def _(tmp):
    b = _bundle(tmp)
    _edit_json(b / "bundle.json", lambda d: d["render"].update(width=16384, height=16384))
    out = tmp / "out" / "big.exr"
    return ["render", str(b), "-o", str(out)], "16384x16384", [out]


@case("sizes", "bundle_render_field_too_big")
def _(tmp):
    b = _bundle(tmp)
    _edit_json(b / "bundle.json", lambda d: d["render"].update(width=10 ** 9))
    out = tmp / "out" / "big.png"
    return ["render", str(b), "-o", str(out)], "render.width", [out]


# mesh scenes (a program that maps textures by uv and tangents) and lights --------------------------
PBR_SOURCE = REPO / "trained" / "di_pbr_set_bricks"


def _pbr_scene(tmp: Path) -> Path:
    folder = tmp / "pbr"
    shutil.copytree(PBR_SOURCE, folder, ignore=shutil.ignore_patterns("preview.png"))
    return folder


def _obj_lines(keep_vt, vt_same=False):
    """The shipped mesh.obj without its vt lines (keep_vt False), or with every vt the same."""
    out = []
    for line in (PBR_SOURCE / "mesh.obj").read_text().splitlines():
        if line.startswith("vt "):
            if keep_vt:
                out.append("vt 0.5 0.5" if vt_same else line)
        elif line.startswith("f ") and not keep_vt:
            out.append("f " + " ".join(c.split("/")[0] for c in line.split()[1:]))
        else:
            out.append(line)
    return "\n".join(out) + "\n"


@case("mesh", "mesh_without_uv")
def _(tmp):
    s = _pbr_scene(tmp)
    (s / "mesh.obj").write_text(_obj_lines(keep_vt=False))
    argv, out = _render_scene(tmp, s)
    return argv, "mesh: mesh.obj has no texture coordinates", [out]


@case("mesh", "mesh_uv_all_identical")
def _(tmp):
    s = _pbr_scene(tmp)
    (s / "mesh.obj").write_text(_obj_lines(keep_vt=True, vt_same=True))
    argv, out = _render_scene(tmp, s)
    return argv, "zero uv area", [out]


_pbr_edit = _scene_json_edit("mesh", _pbr_scene)


_pbr_edit("shape_unknown", lambda d: d.update(mesh={"shape": "cube"}), "mesh.shape")
_pbr_edit("shape_segments_zero", lambda d: d.update(mesh={"shape": "teapot", "segments": 0}), "mesh.segments")
_pbr_edit("shape_segments_1e12", lambda d: d.update(mesh={"shape": "sphere", "segments": 10 ** 12}), "mesh.segments")
_pbr_edit("shape_unknown_field", lambda d: d.update(mesh={"shape": "plane", "radius": 1}), "mesh.radius")
_pbr_edit("light_directional_zero", lambda d: d["lights"].__setitem__(
    0, {"type": "directional", "direction": [0, 0, 0], "intensity": 1}), "lights[0].direction")
_pbr_edit("light_type_spot", lambda d: d["lights"].__setitem__(0, {"type": "spot"}), "lights[0].type")
# the shipped PBR pass reads u_lights as point positions: a directional light is refused, not misdrawn
_pbr_edit("light_directional_old_program", lambda d: d["lights"].__setitem__(
    0, {"type": "directional", "direction": [0, 1, 0], "intensity": 1}), "lights: passes/mesh_pbr_set.frag")


# --- running ------------------------------------------------------------------------------------------
IDS = [(cls, name) for cls, cases in CASES.items() for name in cases]
WORKER = Path(__file__).resolve().with_name("bad_input_worker.py")
TIMEOUT = 120                                   # seconds per case; a child still running is killed
JOBS = max(2, min(8, os.cpu_count() or 2))      # children at once


def _prepare(root: Path, cls: str, name: str) -> dict:
    """Build the case's folder; what the child is to run, and what to compare after."""
    tmp = root / f"{cls}-{name}"
    tmp.mkdir()
    built = CASES[cls][name](tmp)
    argv, expect, outputs = built[:3]
    existing = list(built[3]) if len(built) > 3 else []
    before = {p: p.read_bytes() for p in existing}
    outputs = [p for p in outputs if not p.exists()]   # e.g. a folder given as -o: it stays, no file appears
    folders = {p.parent for p in [*outputs, *existing] if p.parent.is_dir()}
    listing = {d: sorted(os.listdir(d)) for d in folders if d != Path("/proc")}
    return {"argv": argv, "expect": expect, "outputs": outputs, "existing": existing, "before": before,
            "listing": listing, "request": {"module": "inshade.cli", "argv": ["-q", *argv], "cwd": str(tmp)}}


# Controls: the same worker runs these scripts, to show that a child is what the cases need it to
# be (test_child_is_a_limited_interpreter): python script.py's status, traceback and output.
CONTROLS = {
    "allocates_8_GiB": ("data = bytearray(8 << 30)\nprint('allocated', len(data))\n", {}),
    "raises": ("raise RuntimeError('deliberate')\n", {}),
    "exits_3": ("import sys\nprint('to stdout')\nprint('inshade: error: x', file=sys.stderr)\nsys.exit(3)\n", {}),
    "exits_message": ("raise SystemExit('a message')\n", {}),
    "limits_and_folder": ("import json, os, resource, sys\nprint(json.dumps([resource.getrlimit(resource.RLIMIT_AS), "
                          "os.getcwd(), sys.argv, sys.path[0], os.getppid()]))\n", {}),
    "sleeps_past_timeout": ("import time\ntime.sleep(60)\n", {"timeout": 0.5}),
}


def _run_all(root: Path, jobs: dict[object, dict]) -> dict[object, dict]:
    """Run every job's request in the fork server; each job gains rc, stdout, stderr, timed_out."""
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    io = root / "_io"   # outside every case folder (their listings are compared)
    io.mkdir()
    worker = subprocess.Popen([sys.executable, str(WORKER), str(JOBS), str(MEMORY_LIMIT), str(TIMEOUT)],
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                              env=env, cwd=root)
    keys = list(jobs)
    lines = []
    for i, key in enumerate(keys):
        request = dict(jobs[key]["request"], key=i, stdout=str(io / f"{i}.out"), stderr=str(io / f"{i}.err"))
        lines.append(json.dumps(request))
    try:   # each child ends by its TIMEOUT at the latest
        out, err = worker.communicate("\n".join(lines) + "\n", timeout=TIMEOUT * len(keys) / JOBS + 60)
    finally:
        if worker.poll() is None:
            worker.kill()
    done = {r["key"]: r for r in map(json.loads, out.splitlines())}
    assert worker.returncode == 0 and len(done) == len(keys), f"fork server: status {worker.returncode}\n{err}"
    for i, key in enumerate(keys):
        jobs[key].update(rc=done[i]["rc"], timed_out=done[i]["timed_out"],
                         stdout=(io / f"{i}.out").read_text(errors="replace"),
                         stderr=(io / f"{i}.err").read_text(errors="replace"))
    return jobs


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    root = tmp_path_factory.mktemp("bad_inputs")
    jobs = {key: _prepare(root, *key) for key in IDS}
    for name, (source, extra) in CONTROLS.items():
        folder = root / f"control-{name}"
        folder.mkdir()
        (folder / "control.py").write_text(source)
        jobs[("control", name)] = {"request": {"path": str(folder / "control.py"), "argv": ["an", "arg"],
                                               "cwd": str(folder), **extra}}
    return _run_all(root, jobs)


@pytest.mark.parametrize("cls,name", IDS, ids=[f"{c}({len(CASES[c])})-{n}" for c, n in IDS])
def test_bad_input_is_one_line_exit_2(results, cls, name):
    r = results[(cls, name)]
    what = f"inshade {' '.join(r['argv'])}\nstderr:\n{r['stderr']}"
    assert not r["timed_out"], f"still running after {TIMEOUT} s: killed\n{what}"
    assert "Traceback" not in r["stderr"], what
    assert r["rc"] == 2, what
    lines = r["stderr"].splitlines()
    assert len(lines) == 1 and lines[0].startswith("inshade: error: "), what
    assert r["expect"] in lines[0], f"expected {r['expect']!r} in the message\n{what}"
    for p in r["outputs"]:
        assert not p.exists() or p in r["existing"], f"{p} was written\n{what}"
    for p in r["existing"]:
        assert p.read_bytes() == r["before"][p], f"{p} changed\n{what}"
    for d, names in r["listing"].items():
        assert sorted(os.listdir(d)) == names, f"files left in {d}\n{what}"


@pytest.mark.parametrize("name", CONTROLS)
def test_child_is_a_limited_interpreter(results, name):
    """Each case's child is a process of its own under RLIMIT_AS, in its folder, whose status,
    output and traceback are those of `python script.py`: the checks above would see a loader
    that allocates what a file claims (a MemoryError traceback), a crash, a wrong status."""
    r = results[("control", name)]
    folder = Path(r["request"]["cwd"])
    what = f"control {name}: status {r['rc']}\nstdout:\n{r['stdout']}\nstderr:\n{r['stderr']}"
    if name == "sleeps_past_timeout":
        assert r["timed_out"] and r["rc"] == -9, what
        return
    assert not r["timed_out"], what
    if name in ("allocates_8_GiB", "raises"):
        lines = r["stderr"].splitlines()
        assert r["rc"] == 1 and lines[0] == "Traceback (most recent call last):", what
        assert lines[-1] == ("MemoryError" if name == "allocates_8_GiB" else "RuntimeError: deliberate"), what
        assert r["stdout"] == "", what
    elif name == "exits_3":
        assert (r["rc"], r["stdout"], r["stderr"]) == (3, "to stdout\n", "inshade: error: x\n"), what
    elif name == "exits_message":
        assert (r["rc"], r["stdout"], r["stderr"]) == (1, "", "a message\n"), what
    else:
        limit, cwd, argv, path0, parent = json.loads(r["stdout"])
        assert r["rc"] == 0 and r["stderr"] == "", what
        assert limit == [MEMORY_LIMIT, MEMORY_LIMIT], what
        assert Path(cwd) == folder and Path(path0) == folder, what
        assert argv == [str(folder / "control.py"), "an", "arg"], what
        assert parent != os.getpid(), what


def test_fork_server_answers_as_python_m(results):
    """A case (a weights file that claims 1e12 values) run again as a `python -m inshade.cli`
    subprocess under the same limit gives the same status, stdout and stderr as its forked child."""
    r = results[("weights", "tensor_1e12_elements")]
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))

    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))

    p = subprocess.run([sys.executable, "-m", "inshade.cli", *r["request"]["argv"]], capture_output=True, text=True,
                       errors="replace", cwd=r["request"]["cwd"], env=env, timeout=TIMEOUT, preexec_fn=limit)
    assert (p.returncode, p.stdout, p.stderr) == (r["rc"], r["stdout"], r["stderr"]), r["argv"]


def test_corpus_size():
    """Dozens of cases, every class represented (the ids say how many per class)."""
    assert len(IDS) >= 60 and all(len(c) >= 5 for c in CASES.values()), {c: len(v) for c, v in CASES.items()}
