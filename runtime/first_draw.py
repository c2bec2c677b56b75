"""What a draw of the scene pass is about to cost, said before it starts: on a software renderer
the first draw of a program JIT-compiles it (seconds to minutes on llvmpipe), and a view whose last
draw took minutes is warned about. What this machine took before is kept in runtime/draw_history.py.
"""
from __future__ import annotations

import hashlib
import logging
from typing import Callable

from inshade.progress import format_seconds, waiting

from . import draw_history
from .compile_cost import inline_flops

log = logging.getLogger("inshade")
_DRAWN: set[str] = set()   # program keys this process has drawn (their first draw is said once)
SLOW_FRAME_S = 30.0   # a view whose last draw took this long is warned about before it starts


def hash_values(values) -> str:
    return hashlib.sha256(repr(sorted((k, repr(v)) for k, v in dict(values).items())).encode()).hexdigest()[:16]


def first_draw_message(generated, renderer: str = "", previous: float | None = None,
                       shader_cache: bool = False) -> str | None:
    """What a software renderer's first draw of these networks is about to do, from their plans
    and what this machine recorded (``previous``: the seconds of the last first draw of this
    program, None if never; ``shader_cache``: it was compiled with Mesa's shader cache on, and the
    cache is on now): "compiling a network of 4 dense layers up to 64 wide (inline) (llvmpipe JIT at
    the first draw: seconds to minutes; ...)". None when no network has a dense layer."""
    nets = []
    for g in generated:
        plan = getattr(g, "plan", None)
        dense = [r for r in (plan.rows if plan is not None else []) if r.type == "dense"]
        if not dense:
            continue
        dims = [int(d) for r in dense for d in str(r.shape).split("->")[-1:]]
        storage = "+".join(sorted({r.storage for r in dense}))
        nets.append(f"{len(dense)} dense layers up to {max(dims)} wide ({storage})")
    if not nets:
        return None
    what = f"a network of {nets[0]}" if len(nets) == 1 else f"{len(nets)} networks: {'; '.join(nets)}"
    name = str(renderer).split(" ")[0] or "software renderer"
    if previous is not None and shader_cache:
        return f"drawing {what} (compiled before on this machine; Mesa's shader cache should make it quick)"
    if previous is not None:
        return f"compiling {what} ({name} JIT at the first draw; {format_seconds(previous)} last time)"
    return (f"compiling {what} ({name} JIT at the first draw: seconds to minutes; Mesa's shader cache keeps "
            "it for later runs)")


def drawn_here(program_key: str) -> bool:
    """Whether this process drew the program already (the driver holds it compiled)."""
    return program_key in _DRAWN


def first_draw_note(gl: dict, program_key: str, generated, pending: bool) -> tuple[str | None, bool]:
    """(what the pending first draw will do on a software renderer, or None; whether Mesa's
    shader cache had this program last time)."""
    if not (pending and gl.get("software")):
        return None, False
    renderer = gl.get("renderer", "")
    if program_key in _DRAWN:   # this process drew it already: the driver has it, nothing to say
        return None, False
    past = draw_history.lookup(renderer, program_key) if program_key else {}
    cached = draw_history.shader_cache_on() and past.get("shader_cache") is True
    return first_draw_message(generated, renderer, past.get("first_draw_s"), cached), cached


def draw_timed(draw: Callable[[], None], ctx, *, scene, gl: dict, program_key: str, values, generated,
               first: bool, new_view: bool, pixels: int, source: str | None = None) -> float:
    """``draw`` (the scene pass), with what to expect said first: on a software renderer the first
    draw of a program (``first``) JIT-compiles it (the message says what happened last time on this
    machine, and a watcher process shows the seconds going by); a ``new_view`` whose last draw took
    minutes is warned about before it starts. ``source``: the assembled fragment stage (the networks it
    calls are what the JIT is calibrated by). Returns the draw's wall time."""
    renderer = gl.get("renderer", "")
    view = f"{program_key}:{hash_values(values)}"   # a frame's time depends on the settings too
    frame = draw_history.lookup(renderer, view) if program_key else {}
    estimate = frame["frame_s"] * pixels / frame["pixels"] if frame.get("frame_s") and frame.get("pixels") else 0.0
    announce, cached = first_draw_note(gl, program_key, generated, first)
    if announce:
        log.info("%s", announce)
    if estimate >= SLOW_FRAME_S and new_view:
        log.warning("this view took about %s to draw last time at these settings (scaled to this size)",
                    format_seconds(estimate))
    what = "compiling" if announce and announce.startswith("compiling") else "drawing"
    marked = first and program_key and gl.get("software")
    # a program this process drew before (another renderer of the same scene) is the driver's already:
    # its first draw here is no compile, and says nothing of the JIT's speed
    compiled_here = first and program_key not in _DRAWN
    if marked:   # a software driver compiles at the first draw: a crash here is a compile's
        warning = draw_history.compile_started(renderer, program_key, f"{scene.name} ({scene.program})")
        if warning:
            log.warning("%s", warning)
    try:
        with waiting(f"{what} {scene.name}", enabled=bool(announce) or estimate >= SLOW_FRAME_S) as w:
            draw()
            if first or w.enabled:
                ctx.finish()
    finally:   # an exception is not a crash: the mark goes either way
        if marked:
            draw_history.compile_finished(renderer, program_key)
    if first:
        _DRAWN.add(program_key)
        if announce and w.seconds >= 2.0:
            # a first draw far past this view's known frame time was a compile the cache missed
            missed = cached and w.seconds > 3.0 * estimate
            log.info("compiled and drawn in %s%s", format_seconds(w.seconds),
                     " (Mesa's shader cache did not have it)" if missed else "")
        if program_key and gl.get("software") and compiled_here:   # inline_flops: what the JIT is calibrated by
            draw_history.record(renderer, program_key, first_draw_s=round(w.seconds, 3), compiled=True,
                                shader_cache=draw_history.shader_cache_on(),
                                inline_flops=inline_flops(generated, source))
    elif w.enabled or w.seconds >= 1.0:   # a slow frame is remembered, to warn next time
        if program_key:
            draw_history.record(renderer, view, frame_s=round(w.seconds, 3), pixels=pixels)
    return w.seconds
