"""GLSL chunk library: ``assemble()`` turns an entry chunk and its ``#include``s into one program.

See ``library.py`` for the include, define and ``#line`` rules.
"""

from .library import (
    HEADER,
    LIBRARY_DIR,
    LINE_STRIDE,
    Assembled,
    add_search_path,
    add_search_provider,
    find_chunk,
    search_path,
    ShaderCompileError,
    ShaderIncludeError,
    assemble,
    explain_compile_error,
    flatten,
)

__all__ = [
    "HEADER",
    "LIBRARY_DIR",
    "LINE_STRIDE",
    "Assembled",
    "add_search_path",
    "add_search_provider",
    "find_chunk",
    "search_path",
    "ShaderCompileError",
    "ShaderIncludeError",
    "assemble",
    "explain_compile_error",
    "flatten",
]
