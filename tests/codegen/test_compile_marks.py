"""A process that ends while the driver compiles (killed, or crashed inside the driver) leaves a
mark in the draw history, and the next compile of that program says what happened and what to try
(a compile cut off while Mesa writes its shader cache can leave an entry that crashes every run)."""
from __future__ import annotations

import logging
import os
import signal
import subprocess
import sys
import textwrap

import pytest

from inshade.runtime import draw_history
from inshade.runtime.programs import ProgramCache
from inshade.shaders import ShaderCompileError

PROGRAM = ("common/fullscreen.vert", "passes/copy.frag")

# The child compiles PROGRAM and dies inside the compile call, as a driver fault would.
CRASHING_CHILD = textwrap.dedent("""
    import os, signal, moderngl
    from inshade.runtime.context import shared_context
    from inshade.runtime.programs import ProgramCache
    def crash(self, **sources):
        os.kill(os.getpid(), signal.SIGSEGV)
    moderngl.Context.program = crash
    ProgramCache(shared_context()).get(*%r, version="330")
""" % (PROGRAM,))


@pytest.fixture
def history(tmp_path, monkeypatch):
    monkeypatch.setenv("INSHADE_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv("MESA_SHADER_CACHE_DISABLE", raising=False)   # the advice names the cache
    return tmp_path


def test_a_compile_the_driver_crashed_in_is_named_next_time(gl, history, caplog):
    child = subprocess.run([sys.executable, "-c", CRASHING_CHILD], env=os.environ, capture_output=True)
    assert child.returncode == -signal.SIGSEGV, child.stderr.decode()[-2000:]
    with caplog.at_level(logging.WARNING, logger="inshade"):
        ProgramCache(gl).get(*PROGRAM, version="330")
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1
    assert warnings[0].startswith("the last compile of passes/copy.frag on this machine did not finish")
    assert "MESA_SHADER_CACHE_DISABLE=true" in warnings[0] and str(draw_history.mesa_cache_dir()) in warnings[0]
    caplog.clear()   # the mark is gone once a compile finishes: nothing to say the time after
    with caplog.at_level(logging.WARNING, logger="inshade"):
        ProgramCache(gl).get(*PROGRAM, version="330")
    assert not [r for r in caplog.records if r.levelno == logging.WARNING]


def test_a_compile_still_running_elsewhere_or_failing_is_not_a_crash(gl, history, caplog):
    renderer = gl.info["GL_RENDERER"]
    with caplog.at_level(logging.WARNING, logger="inshade"):
        assert draw_history.compile_started(renderer, "k", "x") is None
        draw_history.record(renderer, "k", compiling={"pid": os.getppid(), "what": "x"})   # alive
        assert draw_history.compile_started(renderer, "k", "x") is None
        draw_history.compile_finished(renderer, "k")
        assert "compiling" not in draw_history.lookup(renderer, "k")
        with pytest.raises(ShaderCompileError):   # a compile error is not a crash: the mark goes too
            ProgramCache(gl).get(*PROGRAM, version="330", defines={"main": "broken("})
    assert not [e for e in draw_history._read().values() if "compiling" in e]
