"""The Slang compiler that slangpy ships (its slang-compiler library), called through Slang's C API:
a Slang module with its harness becomes SPIR-V, which wgpu runs like the other targets' code."""
from __future__ import annotations

import ctypes
import importlib.util
import tempfile
from functools import lru_cache
from pathlib import Path

INSTALL_HINT = "pip install slangpy (it carries the Slang compiler)"
# the compiler library's file in slangpy's package, by platform
LIBRARY_NAMES = ("libslang-compiler.so*", "libslang.so*", "slang-compiler.dll", "slang.dll", "libslang*.dylib")


class SlangUnavailable(RuntimeError):
    """No Slang compiler library found."""


@lru_cache(maxsize=1)
def slang_library() -> ctypes.CDLL:
    """slangpy's compiler library, loaded with the C API's signatures."""
    spec = importlib.util.find_spec("slangpy")
    if spec is None or not spec.submodule_search_locations:
        raise SlangUnavailable(f"the slang target compiles with the Slang compiler: {INSTALL_HINT}")
    folder = Path(next(iter(spec.submodule_search_locations)))
    found = [p for pattern in LIBRARY_NAMES for p in sorted(folder.glob(pattern))]
    if not found:
        raise SlangUnavailable(f"slangpy at {folder} holds no Slang compiler library ({', '.join(LIBRARY_NAMES)})")
    lib = ctypes.CDLL(str(found[0]))
    lib.spCreateSession.restype, lib.spCreateSession.argtypes = ctypes.c_void_p, [ctypes.c_char_p]
    lib.spCreateCompileRequest.restype, lib.spCreateCompileRequest.argtypes = ctypes.c_void_p, [ctypes.c_void_p]
    lib.spProcessCommandLineArguments.restype = ctypes.c_int
    lib.spProcessCommandLineArguments.argtypes = [ctypes.c_void_p, ctypes.POINTER(ctypes.c_char_p), ctypes.c_int]
    lib.spCompile.restype, lib.spCompile.argtypes = ctypes.c_int, [ctypes.c_void_p]
    lib.spGetDiagnosticOutput.restype, lib.spGetDiagnosticOutput.argtypes = ctypes.c_char_p, [ctypes.c_void_p]
    lib.spGetEntryPointCode.restype = ctypes.c_void_p
    lib.spGetEntryPointCode.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.POINTER(ctypes.c_size_t)]
    lib.spDestroyCompileRequest.argtypes = [ctypes.c_void_p]
    return lib


@lru_cache(maxsize=1)
def _session() -> int:
    return slang_library().spCreateSession(None)


def compile_spirv(source: str, entry: str = "main") -> bytes:
    """SPIR-V of the compute entry point ``entry`` of a Slang source, as ``slangc -target spirv`` makes it;
    a source the compiler refuses raises RuntimeError with its diagnostics."""
    lib = slang_library()
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "net.slang"
        src.write_text(source)
        # the output path names the code the request keeps; the code is read back from the request. Through
        # Slang's GLSL back end (and glslang): its direct SPIR-V writes an early return as a switch with only
        # a default case, which loses wgpu's device on lavapipe when the branch folds to a constant
        args = [str(src), "-target", "spirv", "-emit-spirv-via-glsl", "-entry", entry, "-stage", "compute",
                "-o", str(Path(tmp) / "net.spv")]
        request = lib.spCreateCompileRequest(_session())
        try:
            argv = (ctypes.c_char_p * len(args))(*(a.encode() for a in args))
            failed = lib.spProcessCommandLineArguments(request, argv, len(args)) < 0 or lib.spCompile(request) < 0
            log = (lib.spGetDiagnosticOutput(request) or b"").decode(errors="replace").strip()
            size = ctypes.c_size_t()
            code = None if failed else lib.spGetEntryPointCode(request, 0, ctypes.byref(size))
            spirv = ctypes.string_at(code, size.value) if code and size.value else b""
        finally:
            lib.spDestroyCompileRequest(request)
    if not spirv:
        raise RuntimeError(f"slang -target spirv: {log or 'no code'}")
    return spirv
