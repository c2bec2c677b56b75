"""Shared fixtures."""

import pytest


@pytest.fixture
def gl():
    """The process-wide headless moderngl context (EGL), made current for this test.

    ``shared_context()`` creates the context once per process; calling it per test re-makes it
    current in case a test created or released another context.
    """
    from inshade.viewer.context import shared_context

    return shared_context()


@pytest.fixture
def gl_limits(gl):
    """The driver's identity and limits (``gl_info``), as codegen's ``limits=`` expects them."""
    from inshade.viewer.context import gl_info

    return gl_info(gl)
