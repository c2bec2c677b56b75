"""Compile assembled programs once per (vertex key, fragment key), with errors mapped to chunks."""

from __future__ import annotations

import hashlib
import logging
import os
import re
import tempfile
import time
from pathlib import Path

import moderngl

from inshade.shaders import Assembled, ShaderCompileError, assemble, explain_compile_error

from . import draw_history

log = logging.getLogger("inshade")
# moderngl's compile log: "GLSL Compiler failed\n\nfragment_shader\n=====\n<driver log>";
# a link failure is "GLSL Linker failed\n\nProgram\n=====\n<driver log>".
_STAGE_HEADING = re.compile(r"^(vertex_shader|fragment_shader)\n=+\n", re.MULTILINE)


def program_key(key: tuple[str, str]) -> str:
    """A stable name of a program's sources (both stages' assembly keys)."""
    return hashlib.sha256(repr(key).encode()).hexdigest()[:24]


def default_dump_dir() -> Path:
    """Where failing assembled sources are written: ``$TMPDIR/inshade-shaders``."""
    return Path(tempfile.gettempdir()) / "inshade-shaders"


class ProgramCache:
    """Programs keyed by both stages' assembly keys (version, defines, chunk hashes).

    ``last_compile_seconds`` is the compile+link wall time of the program returned by the last
    ``get`` (recorded when it was built, so a cache hit reports the original cost). Drivers may
    defer work to the first draw (llvmpipe JIT-compiles fragment shader variants at draw time),
    so this measures the GL compile/link calls, not time-to-first-pixel.
    """

    def __init__(self, ctx: moderngl.Context, dump_dir: str | os.PathLike | None = None):
        self.ctx = ctx
        self.dump_dir = Path(dump_dir) if dump_dir is not None else default_dump_dir()
        self.last_compile_seconds = 0.0
        self._programs: dict[tuple[str, str], tuple[moderngl.Program, float]] = {}

    def get(self, vertex_entry: str, fragment_entry: str, *, version: str = "330",
            defines: dict[str, str | int | float | bool] | None = None,
            chunks: dict[str, str] | None = None) -> moderngl.Program:
        """Assemble both stages and return the cached or freshly built program.

        Raises ``ShaderIncludeError`` if assembly fails and ``ShaderCompileError`` (pointing at
        the chunk file and line, with the assembled source written to ``dump_dir``) if the driver
        rejects it.
        """
        vertex = assemble(vertex_entry, version=version, defines=defines, chunks=chunks)
        fragment = assemble(fragment_entry, version=version, defines=defines, chunks=chunks)
        key = (vertex.key, fragment.key)
        if key not in self._programs:
            start = time.perf_counter()
            renderer, name = self.ctx.info["GL_RENDERER"], program_key(key)
            warning = draw_history.compile_started(renderer, name, fragment_entry)
            if warning:
                log.warning("%s", warning)
            try:
                program = self.ctx.program(vertex_shader=vertex.source, fragment_shader=fragment.source)
            except moderngl.Error as exc:
                raise self._explain(str(exc), vertex, fragment) from None
            finally:
                draw_history.compile_finished(renderer, name)
            self._programs[key] = (program, time.perf_counter() - start)
        program, self.last_compile_seconds = self._programs[key]
        return program

    def key_of(self, program: moderngl.Program) -> str:
        """A stable name of ``program``'s sources (both stages' assembly keys), '' if not cached here."""
        for key, (cached, _) in self._programs.items():
            if cached is program:
                return program_key(key)
        return ""

    def discard(self, program: moderngl.Program) -> None:
        """Drop ``program`` from the cache and release it (a hot-reloaded program replaced it)."""
        for key, (cached, _) in list(self._programs.items()):
            if cached is program:
                del self._programs[key]
                program.release()

    def release(self) -> None:
        """Release every cached program (the owner of a window context, at close)."""
        for program, _ in self._programs.values():
            program.release()
        self._programs.clear()

    @property
    def size(self) -> int:
        """How many programs are cached (not ``__len__``: callers write ``cache or ProgramCache()``)."""
        return len(self._programs)

    def _explain(self, log: str, vertex: Assembled, fragment: Assembled) -> ShaderCompileError:
        paths = {"vertex_shader": vertex.write(self.dump_dir, "vert"),
                 "fragment_shader": fragment.write(self.dump_dir, "frag")}
        heading = _STAGE_HEADING.search(log)
        if heading is None:  # link error: no stage and no location; the .vert.glsl sits beside it
            driver_log = log.split("=\n", 1)[-1]
            message = next((line.strip() for line in driver_log.splitlines() if line.strip()), log.strip())
            return ShaderCompileError(message, chunk=None, line=None,
                                      source_path=paths["fragment_shader"], location="link")
        stage = heading[1]
        assembled = vertex if stage == "vertex_shader" else fragment
        return explain_compile_error(assembled, log[heading.end():], source_path=paths[stage])
