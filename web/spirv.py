"""What a page program's SPIR-V binds and where: read from the module's own decorations.

The WebGPU page binds resources by number and fills uniform buffers by byte offset, where the WebGL2
page asks the driver by name; this reads the numbers and offsets glslang assigned (bindings, the
default uniform block's std140 layout, vertex input locations), numbers the resources afresh and moves a fragment stage's inputs to
the locations its vertex stage wrote them at (glslang places each stage's varyings on its own, where
GL matches them by name).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

MAGIC = 0x07230203
# opcodes
NAME, MEMBER_NAME = 5, 6
TYPE_BOOL, TYPE_INT, TYPE_FLOAT, TYPE_VECTOR, TYPE_MATRIX = 20, 21, 22, 23, 24
TYPE_IMAGE, TYPE_SAMPLER, TYPE_ARRAY, TYPE_STRUCT, TYPE_POINTER = 25, 26, 28, 30, 32
CONSTANT, VARIABLE, DECORATE, MEMBER_DECORATE = 43, 59, 71, 72
# decorations
ARRAY_STRIDE, MATRIX_STRIDE, BUILT_IN, LOCATION, BINDING, DESCRIPTOR_SET, OFFSET = 6, 7, 11, 30, 33, 34, 35
# storage classes
UNIFORM_CONSTANT, INPUT, UNIFORM, OUTPUT = 0, 1, 2, 3
DIMENSIONS = {0: "1d", 1: "2d", 2: "3d", 3: "cube"}
SCALARS = {TYPE_FLOAT: "f", TYPE_BOOL: "u"}   # a bool uniform is a 32-bit word holding 0 or 1
DEFAULT_BLOCK = "gl_DefaultUniformBlock"


class SpirvError(ValueError):
    """A module this reader does not understand (it says what)."""


@dataclass
class Module:
    """A SPIR-V module's words, split into instructions (opcode, operand words) once."""

    words: np.ndarray
    instructions: list[tuple[int, int, int]] = field(default_factory=list)   # (opcode, first operand, end)

    @classmethod
    def parse(cls, data: bytes) -> "Module":
        words = np.frombuffer(data, "<u4").copy()
        if len(words) < 5 or words[0] != MAGIC:
            raise SpirvError("not a SPIR-V module (magic number)")
        m, at = cls(words), 5
        while at < len(words):
            count, opcode = int(words[at]) >> 16, int(words[at]) & 0xFFFF
            if count == 0:
                raise SpirvError(f"instruction of zero words at word {at}")
            m.instructions.append((opcode, at + 1, at + count))
            at += count
        return m

    def ops(self, opcode: int):
        for op, start, end in self.instructions:
            if op == opcode:
                yield start, [int(w) for w in self.words[start:end]]

    def string(self, start: int) -> str:
        raw = self.words[start:].tobytes()
        return raw[: raw.index(b"\0")].decode()

    def to_bytes(self) -> bytes:
        return self.words.tobytes()


@dataclass
class Stage:
    """One stage's interface: ``resources`` [{name, group, binding, kind, ...}] where kind is
    "texture" (with view and sample_type), "sampler", "uniforms" (the default block: member layouts
    in ``uniforms``, its byte size in ``size``) or "block" (a named uniform block, fed from the
    manifest's blocks); ``inputs`` / ``outputs``: location by name."""

    resources: list[dict]
    uniforms: dict[str, dict]
    inputs: dict[str, int]
    outputs: dict[str, int]


def _tables(m: Module):
    names = {ops[0]: m.string(start + 1) for start, ops in m.ops(NAME)}
    members = {(ops[0], ops[1]): m.string(start + 2) for start, ops in m.ops(MEMBER_NAME)}
    decorations: dict[int, dict[int, int]] = {}
    for _, ops in m.ops(DECORATE):
        decorations.setdefault(ops[0], {})[ops[1]] = ops[2] if len(ops) > 2 else 1
    member_decorations: dict[tuple[int, int], dict[int, int]] = {}
    for _, ops in m.ops(MEMBER_DECORATE):
        member_decorations.setdefault((ops[0], ops[1]), {})[ops[2]] = ops[3] if len(ops) > 3 else 1
    types = {}
    for opcode in (TYPE_BOOL, TYPE_INT, TYPE_FLOAT, TYPE_VECTOR, TYPE_MATRIX, TYPE_IMAGE, TYPE_SAMPLER,
                   TYPE_ARRAY, TYPE_STRUCT, TYPE_POINTER):
        for _, ops in m.ops(opcode):
            types[ops[0]] = (opcode, ops[1:])
    constants = {ops[1]: ops[2] for _, ops in m.ops(CONSTANT)}
    return names, members, decorations, member_decorations, types, constants


def _member_layout(types, constants, type_id: int, deco: dict, array_stride: int | None = None) -> dict:
    """A uniform block member as the page packs it: scalar kind, rows, columns, array count, strides."""
    opcode, ops = types[type_id]
    if opcode == TYPE_ARRAY:
        inner = _member_layout(types, constants, ops[0], deco)
        stride = array_stride if array_stride is not None else deco.get(ARRAY_STRIDE)
        return {**inner, "count": constants[ops[1]], "stride": stride}
    cols, matrix_stride = 1, 0
    if opcode == TYPE_MATRIX:
        cols, matrix_stride = ops[1], deco.get(MATRIX_STRIDE, 16)
        opcode, ops = types[ops[0]]
    rows = 1
    if opcode == TYPE_VECTOR:
        rows = ops[1]
        opcode, ops = types[ops[0]]
    if opcode == TYPE_INT:
        kind = "i" if ops[1] else "u"
    elif opcode in SCALARS:
        kind = SCALARS[opcode]
    else:
        raise SpirvError(f"a uniform of type opcode {opcode}: not a number, vector, matrix or array of them")
    return {"kind": kind, "rows": rows, "cols": cols, "matrix_stride": matrix_stride, "count": 1, "stride": 0}


def _layout_bytes(lay: dict) -> int:
    one = lay["matrix_stride"] * (lay["cols"] - 1) + 4 * lay["rows"] if lay["cols"] > 1 else 4 * lay["rows"]
    return one if lay["count"] == 1 else lay["stride"] * (lay["count"] - 1) + one


def reflect(data: bytes) -> Stage:
    m = Module.parse(data)
    names, members, decorations, member_decorations, types, constants = _tables(m)
    resources, uniforms, inputs, outputs = [], {}, {}, {}
    array_strides = {t: d[ARRAY_STRIDE] for t, d in decorations.items() if ARRAY_STRIDE in d}
    for _, (ptr, var, storage, *_) in m.ops(VARIABLE):
        deco = decorations.get(var, {})
        pointee = types[ptr][1][1]
        name = names.get(var, "")
        if storage in (INPUT, OUTPUT):
            if LOCATION in deco and BUILT_IN not in deco:
                (inputs if storage == INPUT else outputs)[name] = deco[LOCATION]
            continue
        if storage not in (UNIFORM_CONSTANT, UNIFORM):
            continue
        at = {"name": name, "group": deco.get(DESCRIPTOR_SET, 0), "binding": deco[BINDING]}
        opcode, ops = types[pointee]
        if opcode == TYPE_IMAGE:
            scalar, scalar_ops = types[ops[0]]
            sample = "float" if scalar == TYPE_FLOAT else "sint" if scalar_ops[1] else "uint"
            view = DIMENSIONS[ops[1]] + ("-array" if ops[3] else "")
            resources.append({**at, "kind": "texture", "view": view, "sample_type": sample})
        elif opcode == TYPE_SAMPLER:
            resources.append({**at, "kind": "sampler"})
        elif opcode == TYPE_STRUCT:
            block = names.get(pointee, "")
            size = 0
            for k, member_type in enumerate(ops):
                mdeco = member_decorations.get((pointee, k), {})
                lay = {"offset": mdeco[OFFSET],
                       **_member_layout(types, constants, member_type, mdeco, array_strides.get(member_type))}
                size = max(size, lay["offset"] + _layout_bytes(lay))
                if block == DEFAULT_BLOCK:
                    uniforms[members[(pointee, k)]] = lay
            kind = "uniforms" if block == DEFAULT_BLOCK else "block"
            resources.append({**at, "name": block, "kind": kind, "size": -(-size // 16) * 16})
        else:
            raise SpirvError(f"{name}: a resource of type opcode {opcode}")
    return Stage(sorted(resources, key=lambda r: (r["group"], r["binding"])), uniforms, inputs, outputs)


def renumber_bindings(data: bytes) -> bytes:
    """The module with its resources numbered 0, 1, 2, ... per descriptor set in declaration order:
    glslang's automatic numbering can give the default uniform block and a texture the same number,
    and a split texture and sampler share their combined one's."""
    m = Module.parse(data)
    sets = {ops[0]: ops[2] for _, ops in m.ops(DECORATE) if ops[1] == DESCRIPTOR_SET}
    order = {ops[1]: k for k, (_, ops) in enumerate(m.ops(VARIABLE))}
    at = {start: ops[0] for start, ops in m.ops(DECORATE) if ops[1] == BINDING}
    counters: dict[int, int] = {}
    for start, target in sorted(at.items(), key=lambda item: order.get(item[1], -1)):
        group = sets.get(target, 0)
        m.words[start + 2] = counters.get(group, 0)
        counters[group] = counters.get(group, 0) + 1
    return m.to_bytes()


def relocate_inputs(data: bytes, locations: dict[str, int]) -> bytes:
    """The module with each named input moved to ``locations[name]`` (its vertex stage's output);
    an input its vertex stage does not write is an error, as GL's link would be."""
    m = Module.parse(data)
    names = {ops[0]: m.string(start + 1) for start, ops in m.ops(NAME)}
    storage = {ops[1]: ops[2] for _, ops in m.ops(VARIABLE)}
    for start, ops in m.ops(DECORATE):
        target, decoration = ops[0], ops[1]
        if decoration != LOCATION or storage.get(target) != INPUT:
            continue
        name = names.get(target, "")
        if name not in locations:
            raise SpirvError(f"fragment input {name}: the vertex stage does not write it")
        m.words[start + 2] = locations[name]
    return m.to_bytes()
