"""Shared fixtures."""
from pathlib import Path

import pytest

from inshade.shaders import add_search_path

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
