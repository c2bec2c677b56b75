"""Atomic outputs (inshade/files.py): a render or codegen that fails halfway leaves no partial
files, and files that were at those paths before are untouched."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from inshade.files import atomic_files, atomic_write


def _names(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def test_atomic_files_commit_together_or_not_at_all(tmp_path):
    a, b = tmp_path / "a.txt", tmp_path / "sub" / "b.bin"
    atomic_write(a, "old")
    with pytest.raises(RuntimeError):
        with atomic_files(a, b) as (ta, tb):
            ta.write_text("new")
            tb.write_bytes(b"x")
            raise RuntimeError("fails after both were written")
    assert a.read_text() == "old" and _names(tmp_path) == ["a.txt", "sub"] and _names(tmp_path / "sub") == []
    with atomic_files(a, b) as (ta, tb):
        assert ta.suffix == ".txt" and tb.parent == b.parent
        ta.write_text("new")
        tb.write_bytes(b"x")
    assert a.read_text() == "new" and b.read_bytes() == b"x" and _names(tmp_path / "sub") == ["b.bin"]


@pytest.mark.parametrize("suffix", [".png", ".exr"])
def test_failing_sidecar_leaves_no_image(tmp_path, suffix):
    from inshade.runtime.headless import save_render

    image = np.full((4, 5, 4), 0.5, np.float32)
    out = tmp_path / f"shot{suffix}"
    save_render(image, {"ok": 1}, out)
    before = out.read_bytes(), Path(f"{out}.json").read_text()
    with pytest.raises(TypeError, match="not JSON serialisable"):
        save_render(image * 0, {"bad": object()}, out)
    assert (out.read_bytes(), Path(f"{out}.json").read_text()) == before
    assert _names(tmp_path) == sorted([out.name, f"{out.name}.json"])
    fresh = tmp_path / "new" / f"x{suffix}"
    with pytest.raises(TypeError):
        save_render(image, {"bad": object()}, fresh)
    assert not fresh.parent.exists() or _names(fresh.parent) == []


def test_failing_codegen_resources_leave_no_glsl(tmp_path, monkeypatch, capsys):
    """`inshade codegen -o net.glsl` with texture storage writes three files; if the resources
    cannot be written, none of them appears."""
    import safetensors.numpy

    from inshade import cli
    from inshade.models import mlp_graph

    bundle = tmp_path / "b"
    mlp_graph(2, [8], 3).export("demo", "demo").save(bundle)
    out = tmp_path / "out" / "net.glsl"

    def broken(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(safetensors.numpy, "save_file", broken)
    assert cli.main(["-q", "codegen", str(bundle), "--storage", "texture", "--no-gl", "-o", str(out)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err == [f"inshade: error: {out}: cannot write (disk full)"], err   # one line, exit 2
    assert _names(out.parent) == []
    monkeypatch.undo()
    assert cli.main(["-q", "codegen", str(bundle), "--storage", "texture", "--no-gl", "-o", str(out)]) == 0
    assert _names(out.parent) == ["net.glsl", "net.glsl.json", "net.resources.safetensors"]
    assert json.loads((out.parent / "net.glsl.json").read_text())["resources_file"] == "net.resources.safetensors"


@pytest.mark.parametrize("umask", [0o022, 0o077, 0o002])
def test_files_get_the_mode_the_umask_gives(tmp_path, umask):
    """Not the temporary's private 0600: another user, a web server or a build step can read them."""
    import os

    old = os.umask(umask)
    try:
        atomic_write(tmp_path / "a.txt", "x")
        with atomic_files(tmp_path / "b.glsl", tmp_path / "sub" / "c.json") as (b, c):
            b.write_text("b")
            c.write_text("c")
    finally:
        os.umask(old)
    for name in ("a.txt", "b.glsl", "sub/c.json"):
        assert (tmp_path / name).stat().st_mode & 0o777 == 0o666 & ~umask, name


def test_a_group_member_that_is_a_folder_leaves_nothing_and_is_named(tmp_path, capsys):
    """`inshade codegen --storage texture -o out/net.glsl` where out/net.resources.safetensors is a folder:
    none of the three files appears, and the error names the resources file."""
    from inshade import cli
    from inshade.models import mlp_graph

    bundle = tmp_path / "b"
    mlp_graph(2, [8], 3).export("demo", "demo").save(bundle)
    out = tmp_path / "out" / "net.glsl"
    (tmp_path / "out" / "net.resources.safetensors").mkdir(parents=True)
    assert cli.main(["-q", "codegen", str(bundle), "--storage", "texture", "--no-gl", "-o", str(out)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err == [f"inshade: error: {out.parent / 'net.resources.safetensors'}: cannot write (is a folder)"], err
    assert _names(out.parent) == ["net.resources.safetensors"]


def test_a_created_folder_is_said_once(tmp_path, caplog):
    import logging

    with caplog.at_level(logging.INFO, logger="inshade"):
        atomic_write(tmp_path / "new" / "deeper" / "a.txt", "x")
        atomic_write(tmp_path / "new" / "deeper" / "b.txt", "x")
    said = [r.getMessage() for r in caplog.records if "created folder" in r.getMessage()]
    assert said == [f"created folder {tmp_path / 'new' / 'deeper'}"]
