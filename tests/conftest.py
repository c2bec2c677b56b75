"""Shared fixtures, and ``--gl-backend egl|osmesa``: the GL backend every context of the run uses
(the same switch as the CLI's flag and ``INSHADE_GL_BACKEND``; subprocesses inherit it).

The tests follow the project's layers: core/, components/, codegen/, convert/, runtime/, scene/,
geometry/, models/, web/, viewer/, bench/ and techniques/<name>/; what checks the whole house
(architecture, layers, words, docs, shipped renders, bad inputs, the CLI) sits here at the top,
with the shared helpers (parity.py, zoo.py, ...)."""
import os
import sys
from pathlib import Path

import pytest

from inshade.runtime.context import BACKEND_ENV, BACKENDS
from inshade.shaders import add_search_path


def pytest_addoption(parser):
    parser.addoption("--gl-backend", choices=BACKENDS, default=None,
                     help=f"GL backend for every context of the run (default: ${BACKEND_ENV}, else egl)")


def pytest_configure(config):
    backend = config.getoption("--gl-backend")
    if backend:
        os.environ[BACKEND_ENV] = backend


def pytest_report_header(config):
    return f"GL backend: {os.environ.get(BACKEND_ENV) or 'egl'}"

# A test file may reuse another layer's test helpers (a technique's tests the component tables'
# generators): every folder of tests is importable by module name, as the top folder is.
TESTS = Path(__file__).resolve().parent
sys.path[1:1] = sorted(str(d.parent) for d in TESTS.glob("*/**/test_*.py") if str(d.parent) not in sys.path)

# Test-only passes (tests/shaders/passes/*_test.frag.glsl) that feed chunks sample inputs.
add_search_path(Path(__file__).resolve().parent / "shaders")


@pytest.fixture
def gl():
    """The process-wide headless moderngl context (EGL), made current for this test.

    ``shared_context()`` creates the context once per process; calling it per test re-makes it
    current in case a test created or released another context.
    """
    from inshade.runtime.context import shared_context

    return shared_context()


@pytest.fixture
def gl_limits(gl):
    """The driver's identity and limits (``gl_info``), as codegen's ``limits=`` expects them."""
    from inshade.runtime.context import gl_info

    return gl_info(gl)


@pytest.fixture(scope="module")
def program_cache():
    """Programs compiled once per test module on the shared context (a module's draws share them)."""
    from inshade.runtime.context import shared_context
    from inshade.runtime.programs import ProgramCache

    return ProgramCache(shared_context())


@pytest.fixture(scope="module")
def one_torch_thread():
    """torch on one thread for a module: two spinning OpenMP threads on a shared 2-core machine run
    small training steps ~10x slower. A module asks with ``pytestmark = pytest.mark.usefixtures(...)``."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)



@pytest.fixture
def fullscreen_test_pass(gl):
    """``make(fragment)``: the full-screen pass of a test fragment shader (tests/shaders/passes/...),
    compiled for this test and released after it."""
    from inshade.runtime.programs import ProgramCache
    from inshade.runtime.render import FullscreenPass

    cache, made = ProgramCache(gl), []

    def make(fragment: str):
        made.append(FullscreenPass(gl, cache.get("common/fullscreen.vert", fragment)))
        return made[-1]
    yield make
    for p in made:
        p.vao.release()
