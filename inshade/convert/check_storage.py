"""Where the check reads a network's dense weights from. Its program is drawn once, so on a software
driver, which JIT-compiles at that draw, compiling literals can cost far more than the draw: a 64 x 4
MLP's literals take ~10 s on llvmpipe, the same weights in a texture 0.6 s (``inshade bench export``).
There the check of storage "auto" reads them from a texture; the numbers are the same under the rule
(each storage's emitter is held to torch by the component tests), renders keep their own storage, and
the bundle's record says which storage was checked. A storage asked for by name is checked as asked.
"""
from __future__ import annotations

CHECK_COMPILE_BUDGET_S = 2.0   # a check's literals expected to compile longer than this read a texture


def quick_storage(bundle, requested: str, limits: dict | None, generated) -> tuple[str, object, str]:
    """(storage, its generated code, why) for the check: ``requested`` and ``generated`` as they are,
    or "texture" with its code and a line saying why."""
    from inshade.codegen import generate
    from inshade.components.dense.emit_plan import is_software
    from inshade.runtime.compile_cost import inline_flops, seconds_per_flop

    if requested != "auto" or generated is None or not is_software(limits or {}):
        return requested, generated, ""
    renderer = str(limits.get("renderer", limits.get("GL_RENDERER", "")))
    flops = inline_flops([generated])
    estimate = flops * seconds_per_flop(renderer)
    if estimate <= CHECK_COMPILE_BUDGET_S:
        return requested, generated, ""
    try:
        quick = generate(bundle, storage="texture", limits=limits)
    except ValueError:   # the weights do not fit a texture here: the literals are checked, slowly
        return requested, generated, ""
    return "texture", quick, (f"check: the weights read from a texture (storage auto's literals would take ~"
                              f"{estimate:.0f} s to compile on {renderer}: {flops} inlined FLOPs); renders "
                              f"keep storage auto")
