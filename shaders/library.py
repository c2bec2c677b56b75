"""Resolve GLSL chunks into one program source, and map driver errors back to chunks.

A program is a list of ``#include <name>`` lines (three.js ``ShaderChunk`` style). A chunk name
is a relative path without the ``.glsl`` suffix: ``lib/colour`` is ``shaders/lib/colour.glsl``.
Generated code (a network) arrives as an in-memory chunk that takes priority over files.

Chunk files are looked up on a search path: this shared library first, then folders added with
``add_search_path`` (e.g. test fixtures), then the folders each added provider names (the
technique registry adds one: every registered technique's ``shaders/`` folder). The library asks
no one else; a name found in two folders is an error, never a silent shadow.

Rules the resolver enforces, so that every program is assembled the same way on every driver:

- The resolver writes the ``#version`` header (plus ES precisions and ``#define`` lines); chunks
  must not declare ``#version`` themselves.
- Each chunk is included once; a later ``#include`` of the same chunk is dropped. A cycle (a chunk
  including one that is still open) is an error naming the chain.
- ``#include`` must not sit inside ``#if``/``#ifdef`` blocks: the resolver does not evaluate the
  preprocessor, so a conditional include would break both include-once and line mapping. Use a
  stub chunk with the same signature instead (select it through ``chunks=``).

Line mapping. Each chunk gets a source-string id (1-based, order of first inclusion; 0 is the
generated header) and ``#line`` markers are emitted at every chunk start and after every include.
GLSL 3.30+/ES 3.00 ``#line N S`` numbers the *next* line N (checked on Mesa and glslang).
Mesa drops the source-string number for many errors (``undeclared identifier`` is reported as
source 0), so the line number alone must identify the chunk: chunk ``id`` line ``n`` is emitted as
line ``id * LINE_STRIDE + n``. A raw log line ``0:3000012(5)`` therefore reads "chunk 3, line 12".
"""

from __future__ import annotations

import hashlib
import json
import numbers
import re
from dataclasses import dataclass, field
from pathlib import Path

LIBRARY_DIR = Path(__file__).resolve().parent
_EXTRA_ROOTS: list[Path] = []
_ROOT_PROVIDERS: list = []     # callables -> [Path]: searched after _EXTRA_ROOTS, in order
HEADER = "<header>"
LINE_STRIDE = 1_000_000

_VERSIONS = {
    "330": ("#version 330 core",),
    "450": ("#version 450 core",),
    "es300": (
        "#version 300 es",
        "precision highp float;",
        "precision highp int;",
        "precision highp sampler2D;",
        "precision highp sampler3D;",
        "precision highp sampler2DArray;",
        "precision highp usampler2D;",
        "precision highp usampler3D;",
        "precision highp usampler2DArray;",
    ),
}
_TARGET_DEFINES = {"330": "INSHADE_TARGET_330", "450": "INSHADE_TARGET_450", "es300": "INSHADE_TARGET_ES300"}

_INCLUDE = re.compile(r"^\s*#\s*include\s*<\s*([^<>\s]+)\s*>\s*(?://.*)?$")
_IF_OPEN = re.compile(r"^\s*#\s*if(?:def|ndef)?\b")
_IF_CLOSE = re.compile(r"^\s*#\s*endif\b")
_VERSION_LINE = re.compile(r"^\s*#\s*version\b")
_CHUNK_NAME = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.\-]*(?:/[A-Za-z0-9_][A-Za-z0-9_.\-]*)*$")
_DEFINE_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")

# First error line of a driver log: Mesa "S:L(C): error: m", glslang/AMD/Intel "ERROR: S:L: m",
# NVIDIA "S(L) : error C1008: m". Warnings are skipped.
# The message keeps the driver's own "error ..." wording; glslang's lacks it, so it is prefixed.
_LOG_FORMATS = (
    (re.compile(r"^\s*(\d+):(\d+)\(\d+\):\s*(.*\berror\b.*)$", re.IGNORECASE), ""),
    (re.compile(r"^\s*ERROR:\s*(\d+):(\d+):\s*(.*)$"), "error: "),
    (re.compile(r"^\s*(\d+)\((\d+)\)\s*:\s*(.*\berror\b.*)$", re.IGNORECASE), ""),
)


class ShaderIncludeError(Exception):
    """A program could not be assembled (unknown chunk, cycle, misplaced directive)."""


class ShaderCompileError(Exception):
    """The driver rejected an assembled program; ``chunk``/``line`` point at the chunk source.

    ``chunk`` and ``line`` are None when the driver gave no location (e.g. link errors).
    """

    def __init__(self, message: str, *, chunk: str | None, line: int | None,
                 source_path: Path | None, location: str | None = None):
        self.message = message
        self.chunk = chunk
        self.line = line
        self.source_path = source_path
        where = location or chunk or "shader"
        if line is not None:
            where = f"{where}:{line}"
        text = f"{where}: {message}"
        if source_path is not None:
            text += f" (assembled source: {source_path})"
        super().__init__(text)


@dataclass(frozen=True)
class Assembled:
    """One assembled program stage: the exact text handed to the driver plus its provenance."""

    entry: str
    source: str
    chunk_ids: dict[int, str]
    chunk_hashes: dict[str, str]
    chunk_paths: dict[str, Path | None] = field(repr=False)  # None for in-memory chunks
    key: str

    @property
    def stage(self) -> str | None:
        """Shader stage guessed from the entry name (``passes/copy.frag`` -> ``frag``), or None."""
        suffix = self.entry.rsplit(".", 1)[-1]
        return suffix if suffix in ("vert", "frag", "geom", "comp") else None

    def locate(self, source_id: int, line: int) -> tuple[str, int]:
        """Map a driver (source-string id, line) to (chunk name, 1-based line in that chunk)."""
        if line >= LINE_STRIDE:
            source_id, line = divmod(line, LINE_STRIDE)
        if source_id not in self.chunk_ids:
            raise KeyError(f"no chunk with source id {source_id} in {self.entry}")
        return self.chunk_ids[source_id], line

    def display_name(self, chunk: str) -> str:
        """A path a reader can open: ``shaders/lib/colour.glsl``, or ``<network>`` if generated."""
        path = self.chunk_paths.get(chunk)
        if path is None:
            return chunk if chunk == HEADER else f"<{chunk}>"
        top = LIBRARY_DIR.parent
        return path.relative_to(top).as_posix() if path.is_relative_to(top) else str(path)

    def write(self, directory: str | Path, stage: str | None = None) -> Path:
        """Write the assembled source to ``<dir>/<key[:16]>.<stage>.glsl`` and return the path.

        ``stage`` defaults to the one guessed from the entry name; without either it is omitted.
        """
        directory = Path(directory)
        directory.mkdir(parents=True, exist_ok=True)
        stage = stage or self.stage
        path = directory / (f"{self.key[:16]}.{stage}.glsl" if stage else f"{self.key[:16]}.glsl")
        from inshade.files import atomic_write

        return atomic_write(path, self.source)


def assemble(entry: str, *, version: str = "330",
             defines: dict[str, str | int | float | bool] | None = None,
             chunks: dict[str, str] | None = None) -> Assembled:
    """Assemble chunk ``entry`` and its includes into one source for the given GLSL target.

    ``version`` is ``"330"``, ``"450"`` or ``"es300"``. ``defines`` become ``#define`` lines
    (sorted by name; bools as 1/0; floats as GLSL float literals with float32 round-trip
    precision). ``chunks`` maps names to in-memory chunk text, overriding files of that name.
    """
    if version not in _VERSIONS:
        raise ValueError(f"unknown GLSL target {version!r}; expected one of {sorted(_VERSIONS)}")
    all_defines = dict(defines or {})
    target = _TARGET_DEFINES[version]
    if target in all_defines:
        raise ValueError(f"{target} is defined by the resolver; do not pass it")
    all_defines[target] = 1

    header = list(_VERSIONS[version])
    header += [f"#define {name} {_define_value(name, all_defines[name])}" for name in sorted(all_defines)]
    resolver = _Resolver(dict(chunks or {}))
    body = resolver.emit(entry, parent=None)

    chunk_ids = {0: HEADER, **{i: name for name, i in resolver.ids.items()}}
    key_material = json.dumps({
        "version": version,
        "defines": [[name, _define_value(name, all_defines[name])] for name in sorted(all_defines)],
        "chunks": [[name, resolver.hashes[name]] for name in resolver.ids],
    })
    return Assembled(
        entry=entry,
        source="\n".join(header + body) + "\n",
        chunk_ids=chunk_ids,
        chunk_hashes=dict(resolver.hashes),
        chunk_paths=dict(resolver.paths),
        key=hashlib.sha256(key_material.encode()).hexdigest(),
    )


def add_search_path(folder) -> None:
    """Let chunk names resolve in ``folder`` too (after the shared library, before techniques)."""
    folder = Path(folder).resolve()
    if not folder.is_dir():
        raise ValueError(f"shader search path: {folder} is not a folder")
    if folder not in _EXTRA_ROOTS:
        _EXTRA_ROOTS.append(folder)


def add_search_provider(provider) -> None:
    """Let chunk names resolve in the folders ``provider()`` returns, asked at each lookup (after
    the shared library and added folders): a registry whose folders can grow registers itself."""
    if provider not in _ROOT_PROVIDERS:
        _ROOT_PROVIDERS.append(provider)


def search_path() -> list[Path]:
    """Folders chunk names resolve in: the shared library, added folders, providers' folders."""
    return [LIBRARY_DIR, *_EXTRA_ROOTS, *(root for provider in _ROOT_PROVIDERS for root in provider())]


def find_chunk(name: str, suffix: str = ".glsl") -> Path | None:
    """The file of chunk ``name`` on the search path, None if there is none; a name found in
    two folders is a ShaderIncludeError. ``suffix`` finds the chunk's version in another shading
    language (``.wgsl``, ``.hlsl``)."""
    found = [root / f"{name}{suffix}" for root in search_path() if (root / f"{name}{suffix}").is_file()]
    if len(found) > 1:
        raise ShaderIncludeError(f"chunk <{name}> is ambiguous: {found[0]} and {found[1]}")
    return found[0] if found else None


def flatten(entry: str, *, chunks: dict[str, str] | None = None,
            defines: dict[str, str | int | float | bool] | None = None) -> str:
    """Chunk ``entry`` with its includes expanded, without a header or ``#line`` markers:
    for pasting generated code into another engine's shader. ``defines`` become ``#define`` lines
    before it, as in ``assemble``."""
    lines = [f"#define {name} {_define_value(name, value)}" for name, value in sorted((defines or {}).items())]
    return "\n".join(lines + _Resolver(dict(chunks or {}), line_markers=False).emit(entry, parent=None)) + "\n"


def explain_compile_error(assembled: Assembled, driver_log: str, *,
                          source_path: Path | None = None) -> ShaderCompileError:
    """Turn a driver log into a ShaderCompileError pointing at the first error's chunk and line."""
    for log_line in driver_log.splitlines():
        for pattern, prefix in _LOG_FORMATS:
            match = pattern.match(log_line)
            if match is None:
                continue
            source_id, line, message = int(match[1]), int(match[2]), prefix + match[3].strip()
            try:
                chunk, chunk_line = assembled.locate(source_id, line)
            except KeyError:
                return ShaderCompileError(log_line.strip(), chunk=None, line=None, source_path=source_path)
            return ShaderCompileError(message, chunk=chunk, line=chunk_line, source_path=source_path,
                                      location=assembled.display_name(chunk))
    message = next((s.strip() for s in driver_log.splitlines() if "error" in s.lower()), driver_log.strip())
    return ShaderCompileError(message, chunk=None, line=None, source_path=source_path)


def _define_value(name: str, value: str | int | float | bool) -> str:
    if not _DEFINE_NAME.match(name):
        raise ValueError(f"invalid #define name {name!r}")
    if isinstance(value, bool):
        return "1" if value else "0"
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, numbers.Real):
        value = float(value)
        if value != value or value in (float("inf"), float("-inf")):
            raise ValueError(f"#define {name}: {value} has no GLSL literal")
        text = "%.9g" % value
        return text if any(c in text for c in ".e") else text + ".0"
    if isinstance(value, str) and "\n" not in value:
        return value
    raise TypeError(f"#define {name}: unsupported value {value!r}")


class _Resolver:
    """Depth-first include expansion with include-once and cycle detection."""

    def __init__(self, memory_chunks: dict[str, str], line_markers: bool = True):
        self.memory = memory_chunks
        self.line_markers = line_markers
        self.ids: dict[str, int] = {}
        self.hashes: dict[str, str] = {}
        self.paths: dict[str, Path | None] = {}
        self.open: list[str] = []

    def load(self, name: str, parent: tuple[str, int] | None) -> str:
        where = f" (included from {parent[0]}:{parent[1]})" if parent else ""
        if name in self.memory:
            self.paths[name] = None
            return self.memory[name]
        if not _CHUNK_NAME.match(name) or ".." in name.split("/"):
            raise ShaderIncludeError(f"invalid chunk name {name!r}{where}")
        path = find_chunk(name)
        if path is None:
            roots = ", ".join(str(r) for r in search_path())
            raise ShaderIncludeError(f"unknown chunk <{name}>{where}: no in-memory chunk and no {name}.glsl "
                                     f"in {roots}")
        self.paths[name] = path
        return path.read_text()

    def emit(self, name: str, parent: tuple[str, int] | None) -> list[str]:
        text = self.load(name, parent)
        chunk_id = self.ids[name] = len(self.ids) + 1
        self.hashes[name] = hashlib.sha256(text.encode()).hexdigest()
        lines = text.splitlines()
        if len(lines) >= LINE_STRIDE:
            raise ShaderIncludeError(f"chunk {name} is longer than {LINE_STRIDE - 1} lines")
        self.open.append(name)
        marker = _line_marker if self.line_markers else lambda *_: f"// ---- <{name}>"
        out = [marker(chunk_id, 1, name)]
        depth = 0
        for number, line in enumerate(lines, start=1):
            if _VERSION_LINE.match(line):
                raise ShaderIncludeError(f"{name}:{number}: chunks must not declare #version; assemble() writes it")
            depth += bool(_IF_OPEN.match(line)) - bool(_IF_CLOSE.match(line))
            include = _INCLUDE.match(line)
            if include is None:
                out.append(line)
                continue
            child = include[1]
            if depth > 0:
                raise ShaderIncludeError(f"{name}:{number}: #include <{child}> inside #if; include unconditionally "
                                         "and select a stub chunk instead")
            if child in self.open:
                chain = " -> ".join(self.open[self.open.index(child):] + [child])
                raise ShaderIncludeError(f"include cycle: {chain} (at {name}:{number})")
            if child in self.ids:
                out.append(f"// #include <{child}>: already included")
                continue
            out += self.emit(child, parent=(name, number))
            out.append(marker(chunk_id, number + 1, name))
        self.open.pop()
        return out


def _line_marker(chunk_id: int, line: int, name: str) -> str:
    return f"#line {chunk_id * LINE_STRIDE + line} {chunk_id} // {name}"
