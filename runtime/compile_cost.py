"""What a program's first draw will cost on a software driver, said before it is drawn. llvmpipe
JIT-compiles a program at its first draw, and the time grows with the dense layers written as
literals (``inshade bench startup``: 11-19 s for the PRT programs' ~36k inlined FLOPs, 2-3 s with the
same weights in a texture), so the estimate is the program's inlined FLOPs per evaluation (of the
networks it calls in the branches its defines keep: shaders/active.py) times this driver's seconds per
FLOP: the median over the cold first draws this machine's draw history recorded
(runtime/draw_history.py), else the default measured on llvmpipe.
"""
from __future__ import annotations

import statistics

from inshade.shaders.active import Unevaluable, called

from . import draw_history

DEFAULT_S_PER_INLINE_FLOP = 3e-4   # llvmpipe (LLVM 15, 2 cores): median of inshade bench startup's cold draws
MIN_FLOPS = 5000                   # smaller programs compile in well under a second: not a measure of the JIT
MIN_RECORDS = 3                    # cold first draws this machine needs before its own rate is used
SLOW_COMPILE_S = 5.0               # a first draw expected to take longer is said before it starts


def inline_flops(generated, source: str | None = None) -> int:
    """FLOPs per evaluation of the dense layers written as literals, over every network of a program, or
    over those its assembled ``source`` calls in the branches its defines select (a program that picks
    one of several networks by a define compiles only that one)."""
    called = _called(generated, source)
    return sum(r.flops for g in generated if g.function in called for r in g.plan.rows
               if r.type == "dense" and r.storage == "inline")


def _called(generated, source: str | None) -> set[str]:
    names = {g.function for g in generated}
    if source is None:
        return names
    try:
        return called(source, names)
    except Unevaluable:   # a directive not read here: every network counts
        return names


def seconds_per_flop(renderer: str) -> float:
    """This driver's JIT seconds per inlined FLOP: the median of its recorded cold first draws of
    programs of at least MIN_FLOPS, once there are MIN_RECORDS of them; else the default. Only draws
    that compiled (``compiled``: the program was new to its process) count."""
    rates = [e["first_draw_s"] / e["inline_flops"] for e in draw_history.entries(renderer)
             if e.get("shader_cache") is False and e.get("compiled") is True and isinstance(e.get("inline_flops"), int)
             and e["inline_flops"] >= MIN_FLOPS and isinstance(e.get("first_draw_s"), (int, float))]
    return statistics.median(rates) if len(rates) >= MIN_RECORDS else DEFAULT_S_PER_INLINE_FLOP


def first_draw_estimate(gl: dict, program_key: str, generated, source: str | None = None) -> float | None:
    """Seconds the first draw of this program will take on this software driver with a cold shader
    cache: what it took last time it was drawn cold here, else the estimate (of the networks the
    assembled fragment ``source`` calls, where given); None on a GPU driver."""
    if not gl.get("software"):
        return None
    renderer = gl.get("renderer", "")
    past = draw_history.lookup(renderer, program_key) if program_key else {}
    if past.get("shader_cache") is False and past.get("compiled") is True and isinstance(past.get("first_draw_s"),
                                                                                         (int, float)):
        return float(past["first_draw_s"])
    return inline_flops(generated, source) * seconds_per_flop(renderer)
