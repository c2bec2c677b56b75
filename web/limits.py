"""WebGL2's limits: what codegen plans against for a page, and what the page checks on load.

The values are the minimums the WebGL 2.0 specification guarantees (OpenGL ES 3.0's "Implementation
Dependent Values" tables, and WebGL2 §5.x), so an exported page runs on every WebGL2 browser; the page
compares them with the browser's own on load and says which one it lacks. A desktop GL 3.3 minimum
is lower for textures (1024) and higher for draw buffers (8).
"""
from __future__ import annotations

WEBGL2 = {
    "GL_MAX_TEXTURE_SIZE": 2048,
    "GL_MAX_3D_TEXTURE_SIZE": 256,
    "GL_MAX_ARRAY_TEXTURE_LAYERS": 256,
    "GL_MAX_UNIFORM_BLOCK_SIZE": 16384,
    "GL_MAX_FRAGMENT_UNIFORM_BLOCKS": 12,
    "GL_MAX_FRAGMENT_UNIFORM_COMPONENTS": 896,   # GL_MAX_FRAGMENT_UNIFORM_VECTORS 224 x 4
    "GL_MAX_TEXTURE_IMAGE_UNITS": 16,
    "GL_MAX_COMBINED_TEXTURE_IMAGE_UNITS": 32,
    "GL_MAX_DRAW_BUFFERS": 4,
    # the page runs on the visitor's GPU, not on the machine that exports it: storage "auto" chooses
    # as for a GPU (inline literals only for small networks: big literal programs stall browsers)
    "renderer": "WebGL2",
    "software": False,
}

# Always needed: the passes render into RGBA32F / RG32F / R32F targets.
BASE_EXTENSIONS = ("EXT_color_buffer_float",)
# Needed by a resource: (texture dtype, filtered) -> extension; f4 linear filtering is optional in WebGL2,
# 16-bit normalised textures are an extension.
TEXTURE_EXTENSIONS = {("f4", True): "OES_texture_float_linear", ("nu2", False): "EXT_texture_norm16",
                      ("nu2", True): "EXT_texture_norm16"}


class WebLimitError(ValueError):
    """An asset that WebGL2 cannot draw; the message names what it lacks."""
