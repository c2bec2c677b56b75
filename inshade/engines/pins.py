"""A network's ports as an engine node's pins (1 to 4 floats each), and the statements that move
their lanes in and out of the network's float4 blocks."""
from __future__ import annotations

import re
from dataclasses import dataclass

LANES = "xyzw"


@dataclass(frozen=True)
class Pin:
    name: str      # the node's pin (an HLSL identifier)
    dim: int       # 1 to 4 floats
    lane: int      # first lane in the concatenated inputs or outputs

    @property
    def type(self) -> str:
        return "float" if self.dim == 1 else f"float{self.dim}"


# names a pin cannot take: HLSL's keywords and types a port name may well be, and the names the
# node's code and its engine use themselves
RESERVED = {"in", "out", "inout", "float", "half", "int", "uint", "bool", "return", "struct", "static", "const",
            "register", "sampler", "texture", "vector", "matrix", "line", "point", "triangle", "Parameters"}


def pins(ports, taken=()) -> list[Pin]:
    """The node pins of ``ports``, in order: one per port of up to 4 lanes, else one per 4 lanes; a
    name that is reserved or in ``taken`` (the other side's pins) gets a ``_pin`` suffix."""
    out, lane = [], 0
    taken = set(taken) | RESERVED
    for p in ports:
        ident = re.sub(r"\W", "_", p.name)
        ident = ident + "_pin" if ident in taken or ident.startswith("inshade_") or ident[0].isdigit() else ident
        if p.dim <= 4:
            out.append(Pin(ident, p.dim, lane))
        else:
            out += [Pin(f"{ident}_{k}", min(4, p.dim - 4 * k), lane + 4 * k) for k in range(-(-p.dim // 4))]
        lane += p.dim
    return out


def lane_of(array: str, lane: int) -> str:
    return f"{array}[{lane // 4}].{LANES[lane % 4]}"


def pack(from_pins: list[Pin], array: str, n_blocks: int) -> list[str]:
    """Statements putting the pins' lanes into the float4 array ``array`` (zero first)."""
    lines = [f"{array}[{b}] = (float4)0;" for b in range(n_blocks)]
    for p in from_pins:
        lines += [f"{lane_of(array, p.lane + k)} = {p.name if p.dim == 1 else p.name + '.' + LANES[k]};"
                  for k in range(p.dim)]
    return lines


def unpack(to_pins: list[Pin], array: str) -> list[str]:
    """Statements setting each pin from the lanes of the float4 array ``array``."""
    lines = []
    for p in to_pins:
        lanes = [lane_of(array, p.lane + k) for k in range(p.dim)]
        lines.append(f"{p.name} = {lanes[0] if p.dim == 1 else p.type + '(' + ', '.join(lanes) + ')'};")
    return lines
