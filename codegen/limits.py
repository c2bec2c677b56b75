"""GL limits codegen plans against, and the error raised when a resource cannot fit them.

``generate(..., limits=...)`` takes the context's queried limits (``runtime.context.gl_info``,
plus any override). A limit missing from that dict means the OpenGL 3.3 core minimum (the
"Implementation Dependent Values" tables 23.5x of the GL 3.3 core specification), so code
generated without a context fits every GL 3.3 driver:

    GL_MAX_TEXTURE_SIZE                  1024    width and height of a 2D texture
    GL_MAX_3D_TEXTURE_SIZE                256    each side of a 3D texture
    GL_MAX_ARRAY_TEXTURE_LAYERS           256    layers of a 2D texture array
    GL_MAX_UNIFORM_BLOCK_SIZE           16384    bytes of one std140 block (ubo dense layers)
    GL_MAX_FRAGMENT_UNIFORM_BLOCKS         12    blocks one fragment shader may declare
    GL_MAX_FRAGMENT_UNIFORM_COMPONENTS   1024    default-block uniform components (the generated
                                                 code declares only samplers there)
    GL_MAX_TEXTURE_IMAGE_UNITS             16    samplers one fragment shader may use
    GL_MAX_COMBINED_TEXTURE_IMAGE_UNITS    48    samplers of one program, all stages
    GL_MAX_DRAW_BUFFERS                     8    colour outputs of one pass (4 lanes each)
"""
from __future__ import annotations

GL33_MINIMUMS = {
    "GL_MAX_TEXTURE_SIZE": 1024,
    "GL_MAX_3D_TEXTURE_SIZE": 256,
    "GL_MAX_ARRAY_TEXTURE_LAYERS": 256,
    "GL_MAX_UNIFORM_BLOCK_SIZE": 16384,
    "GL_MAX_FRAGMENT_UNIFORM_BLOCKS": 12,
    "GL_MAX_FRAGMENT_UNIFORM_COMPONENTS": 1024,
    "GL_MAX_TEXTURE_IMAGE_UNITS": 16,
    "GL_MAX_COMBINED_TEXTURE_IMAGE_UNITS": 48,
    "GL_MAX_DRAW_BUFFERS": 8,
    # GLSL 3.30 and ES 3.00 have no storage buffers
    "GL_MAX_SHADER_STORAGE_BLOCK_SIZE": 0,
    "GL_MAX_FRAGMENT_SHADER_STORAGE_BLOCKS": 0,
}


# storage buffers a stage keeps for the caller (a compute pass's inputs and outputs): a network's own
# storage buffers plan around them
STORAGE_BUFFERS_RESERVED = 2

# Mesa's llvmpipe ends every loop of a pixel once its loops, all together, have iterated 65535
# times (LP_MAX_TGSI_LOOP_ITERATIONS, shared by every loop in a shader): the work past it is lost
# without an error, e.g. a sphere tracer calling a looped network stops marching. No other driver
# measured has such a cap.
LOOP_ITERATION_CAPS = {"llvmpipe": 65535}


def loop_iteration_cap(limits: dict) -> int | None:
    """The driver's cap on a pixel's loop iterations (all loops together), or None."""
    renderer = str(limits.get("renderer", limits.get("GL_RENDERER", ""))).lower()
    return next((cap for name, cap in LOOP_ITERATION_CAPS.items() if name in renderer), None)


class LimitError(ValueError):
    """A network (or one of its GL resources) does not fit the context's limits. The message
    names the node or resource, the limit and both values; planned against a GL 3.3 minimum, it
    says how to plan against a real machine's limits instead."""

    def __init__(self, message: str):
        if "GL 3.3 minimum" in message:
            message += ("; these are GL 3.3's minimums: generate(..., limits=machine_limits()) (inshade.runtime."
                        "context) plans with this machine's (inshade codegen does when it can make a context), "
                        "limits={...} with another's")
        super().__init__(message)


def limit(limits: dict, name: str) -> int:
    """The context's value of ``name``, or the GL 3.3 minimum when the dict lacks it."""
    value = limits.get(name)
    return int(GL33_MINIMUMS[name] if value is None else value)


def source(limits: dict, name: str) -> str:
    """Where a limit's value came from, for the plan: a target's own table (codegen/targets.py:
    the API's name for it), the context (or override), or the GL 3.3 table."""
    named = limits.get("limit_sources", {}).get(name)
    if named:
        return named
    return "context" if limits.get(name) is not None else "GL 3.3 minimum"
