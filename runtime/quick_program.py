"""The weight storage a short job draws with on a software driver. llvmpipe JIT-compiles a program at
its first draw, and literals take far longer to compile than the same weights read from a texture
(``inshade bench startup``: the PRT programs 11-19 s inline, 2-7 s from a texture) while running a few
times faster (1024 x 1024: 0.9 s inline, 3.7 s from a texture). So a job of a few frames at ``auto``
storage draws with the texture where the estimates say the whole job ends sooner: the compile
estimate of the program as set (runtime/compile_cost.py) against the quick program's (what it took
here before, else QUICK_FIRST_DRAW_S) plus the frames' extra gathers. Both programs are under the
parity rule: the pixels differ by float rounding at most.
"""
from __future__ import annotations

from inshade.progress import format_seconds

from .compile_cost import first_draw_estimate, inline_flops
from .first_draw import drawn_here, first_draw_note
from .scene_program import plan_scene_program, planned_program

QUICK_STORAGE = "texture"   # weights read in loops: the quickest compile of the storages on llvmpipe
QUICK_MIN_S = 7.0           # a program expected to compile quicker than this is drawn as set
# the first draw of a texture program this machine has not drawn before: the median of the shipped
# programs past QUICK_MIN_S inline (inshade bench startup, llvmpipe, 2 cores: 1.9-7.4 s)
QUICK_FIRST_DRAW_S = 3.0
# extra frame seconds per pixel per dense FLOP read from a texture rather than literals (llvmpipe,
# 2 cores, 1024 x 1024: 6e-11 for the UV-free material, 8e-11 PRT, 1.8e-10 neural appearance)
S_PER_GATHERED_FLOP = 1e-10


def _planned(renderer, values: dict) -> tuple[list, str, str]:
    """The networks ``values`` generate, the draw history's name of their program and its fragment stage:
    planned, not compiled."""
    generated, defines, chunks = plan_scene_program(renderer.scene, renderer.spec, renderer.bundles, values=values,
                                                    gl=renderer.gl, target=renderer.target,
                                                    sdf_bundle=renderer.sdf_bundle)
    key, source = planned_program(renderer.scene, defines, chunks, renderer.target)
    return generated, key, source


def _first_draw(gl: dict, generated, key: str, source: str) -> tuple[float, bool]:
    """(the first draw's estimate, whether this machine measured it): 0 when this process drew the program
    already or Mesa's shader cache has it."""
    if drawn_here(key) or first_draw_note(gl, key, generated, True)[1]:
        return 0.0, True
    measured = first_draw_estimate(gl, key, [])   # what it took here before, else 0
    return (measured, True) if measured else (first_draw_estimate(gl, key, generated, source) or 0.0, False)


def gathered_flops(generated, source: str) -> int:
    """A pixel's dense FLOPs that the literals hold: what a texture would read instead (each network's
    FLOPs times the evaluations a pixel may make: a march's steps)."""
    return sum(inline_flops([g], source) * g.plan.calls for g in generated)


def quick_first_draw(renderer, values: dict) -> float:
    """The first draw of the QUICK_STORAGE variant of the program ``values`` make: what it took here
    before (0 where Mesa's cache holds it), else QUICK_FIRST_DRAW_S."""
    quick, known = _first_draw(renderer.gl, *_planned(renderer, {**values, "storage": QUICK_STORAGE}))
    return quick if known else QUICK_FIRST_DRAW_S


def quick_storage(renderer, pixels: int, frames: int = 1) -> tuple[str, str | None]:
    """The storage a job of ``frames`` frames of ``pixels`` pixels ends sooner with, for a renderer
    about to build its program at storage ``auto`` on a software driver: (QUICK_STORAGE, why) where
    the estimates say so, else (the storage as set, None)."""
    values = renderer.values
    if not renderer.gl.get("software") or values.get("storage") != "auto":
        return values.get("storage", "auto"), None
    generated, key, source = _planned(renderer, values)
    as_set = _first_draw(renderer.gl, generated, key, source)[0]
    if as_set < QUICK_MIN_S:
        return "auto", None
    gathered = gathered_flops(generated, source) * pixels * frames * S_PER_GATHERED_FLOP
    quick = quick_first_draw(renderer, values) + gathered
    if quick >= as_set:
        return "auto", None
    name = str(renderer.gl.get("renderer", "")).split(" ")[0]
    return QUICK_STORAGE, (f"storage {QUICK_STORAGE} for this job: ~{format_seconds(quick)} to compile and draw, "
                           f"where storage auto's literals would take ~{format_seconds(as_set)} to compile on "
                           f"{name} (--storage inline draws them)")
