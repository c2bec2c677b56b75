"""Parity the user sees: a bundle's generated GLSL, run through the GL driver, against the source
it came from (the user's torch module, or onnxruntime for an ONNX file), on the same inputs.

The rule is the parity suite's: |glsl - source| <= 1e-5 * max(1, |source|) elementwise
(tests/parity.py). ``check`` returns the numbers; ``CheckResult.line()`` is what export and
convert print, e.g. ``max |glsl - source| = 3.1e-07 (rule 1e-05): ok``.
"""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import numpy as np

from .lowering import Float64Unavailable

RULE = 1e-5
RANDOM_ROWS = 1024
# The conditioning rule: where fp32 itself is far from the exact answer (a SIREN's sin arguments in
# the hundreds), the shader passes when it is no farther from the float64 answer than this many
# times the source's own fp32 distance from it.
CONDITIONING = 2.0


@dataclass(frozen=True)
class CheckResult:
    max_abs: float            # max |glsl - source|
    max_scaled: float         # max |glsl - source| / max(1, |source|): the rule's quantity
    worst: tuple              # (row, lane) of the worst scaled error
    rows: int
    gl_renderer: str
    storage: str
    seconds: float
    rule: float = RULE
    glsl_f64: float | None = None     # max |glsl - f64| / max(1, |f64|), when the rule alone fails
    source_f64: float | None = None   # max |source - f64| / max(1, |f64|): fp32's own distance
    f64_missing: str = ""             # why there is no float64 answer, when there is none
    language: str = "glsl"            # the shading language checked (its printer's name)
    reference: str = "source"         # what it is checked against: the source, or a quantized network's twin

    @property
    def conditioned(self) -> bool:
        """Accepted by the conditioning rule (not by the 1e-5 rule)."""
        return (self.max_scaled > self.rule and self.glsl_f64 is not None and self.source_f64 is not None
                and self.glsl_f64 <= CONDITIONING * self.source_f64)

    @property
    def ok(self) -> bool:
        return bool(self.max_scaled <= self.rule or self.conditioned)

    def line(self) -> str:
        verdict = "ok" if self.ok else f"FAILED at row {self.worst[0]}, output lane {self.worst[1]}"
        head = f"max |{self.language} - {self.reference}| = {self.max_scaled:.2g}"
        if self.max_scaled <= self.rule:
            return f"{head} (rule {self.rule:g}): {verdict}"
        if self.glsl_f64 is None:
            why = f"; no float64 answer ({self.f64_missing})" if self.f64_missing else ""
            return f"{head} (rule {self.rule:g}{why}): {verdict}"
        return (f"{head}; |{self.language} - f64| = {self.glsl_f64:.2g} vs |{self.reference} - f64| = "
                f"{self.source_f64:.2g} (rule "
                f"{self.rule:g}, or within {CONDITIONING:g}x of the source's own fp32 error): "
                f"{verdict + ' (conditioning)' if self.ok else verdict}")

    def record(self) -> dict:
        """What a bundle's provenance keeps of the check."""
        out = {"max_abs": self.max_abs, "max_scaled": self.max_scaled, "rule": self.rule, "ok": self.ok,
               "rows": self.rows, "gl_renderer": self.gl_renderer, "storage": self.storage}
        if self.glsl_f64 is not None:
            out.update(glsl_f64=self.glsl_f64, source_f64=self.source_f64, conditioning=CONDITIONING,
                       by_conditioning=self.conditioned)
        return out


def finite_rows(example: np.ndarray) -> np.ndarray:
    """The example's rows without NaN or infinities (a driver's NaN and inf handling is its own:
    GLSL leaves max(NaN, 0) and the like undefined, so such rows are left out of the check)."""
    example = np.asarray(example, np.float32).reshape(len(example), -1)
    return example[np.isfinite(example).all(1)]


def check_inputs(example: np.ndarray, seed: int = 0, rows: int = RANDOM_ROWS) -> np.ndarray:
    """The example's finite rows, then ``rows`` uniform random rows in their range, lane by lane."""
    example = finite_rows(example)
    lo, hi = (example.min(0), example.max(0)) if len(example) else (np.full(example.shape[1], -1.0),) * 2
    lo, hi = np.clip(lo.astype(np.float64), -1e37, 1e37), np.clip(hi.astype(np.float64), -1e37, 1e37)
    wide = np.where(hi > lo, hi, lo + 1.0)   # a constant lane still gets a unit range
    rng = np.random.default_rng(seed)
    return np.concatenate([example, rng.uniform(lo, wide, (rows, example.shape[1])).astype(np.float32)])


def scaled_errors(glsl: np.ndarray, ref: np.ndarray) -> np.ndarray:
    glsl, ref = np.asarray(glsl, np.float64), np.asarray(ref, np.float64)
    with np.errstate(invalid="ignore"):   # inf - inf: judged by the finiteness test below
        err = np.abs(glsl - ref) / np.maximum(1.0, np.abs(ref))
    return np.where(np.isfinite(glsl) == np.isfinite(ref), np.where(np.isfinite(err), err, 0.0), np.inf)


def evaluate(bundle, inputs: np.ndarray, *, storage: str = "auto", ctx=None, limits=None, lut_filter: str = "exact",
             generated=None, target: str = "330"):
    """(outputs [N, out_dim] of the bundle's generated code through a real driver, the driver's name,
    storage used); the code planned against ``limits`` (default: the driver's, or for a target other than
    OpenGL its API's), unless ``generated`` is given. ``target``: 330 (OpenGL), or wgsl / vulkan / hlsl /
    slang, run by the compute drivers (inshade.runtime.compute)."""
    from inshade.codegen import generate
    from inshade.codegen.targets import target as find_target

    if not find_target(target).opengl:
        from inshade.runtime.compute import run_target

        if generated is None:
            generated = generate(bundle, storage=storage, lut_filter=lut_filter, limits=limits, target=target)
        out, device = run_target(generated, np.asarray(inputs, np.float32), target)
        return out, device, storage
    from inshade.runtime.context import gl_info, shared_context
    from inshade.runtime.network import NetworkEvaluator

    ctx = shared_context() if ctx is None else ctx
    if generated is None:
        generated = generate(bundle, storage=storage, lut_filter=lut_filter,
                             limits=gl_info(ctx) if limits is None else limits)
    ev = NetworkEvaluator(ctx, generated)
    try:
        out = ev(np.asarray(inputs, np.float32))
    finally:
        ev.release()
        ev.program.release()
    return out, ctx.info["GL_RENDERER"], storage


def compare(glsl: np.ndarray, ref: np.ndarray, renderer: str, storage: str, seconds: float) -> CheckResult:
    if glsl.shape != ref.shape:
        raise ValueError(f"the GLSL gives {list(glsl.shape)}, the source {list(ref.shape)}")
    err = scaled_errors(glsl, ref)
    worst = np.unravel_index(int(np.argmax(err)), err.shape) if err.size else (0, 0)
    finite = np.isfinite(glsl) & np.isfinite(ref)
    max_abs = float(np.abs(glsl[finite] - ref[finite]).max()) if finite.any() else 0.0
    return CheckResult(max_abs, float(err.max()) if err.size else 0.0, tuple(int(i) for i in worst), len(ref),
                       renderer, storage, seconds)


def check(source, bundle, inputs, *, storage: str = "auto", ctx=None, shapes=None, limits=None,
          generated=None, target: str = "330") -> CheckResult:
    """Run ``bundle``'s GLSL on ``inputs`` ([N, in_dim] concatenated, or a tuple of arrays, one per
    input) and compare with ``source``: a torch module (called on the inputs split per bundle
    input, each reshaped to [N, *shape] when ``shapes`` gives one per input) or an ONNX file path /
    ModelProto (onnxruntime). ``generated``: the bundle's GLSL already planned (else generated here).
    ``target``: the shading language checked (``evaluate``)."""
    from inshade.bundle import Bundle, load
    from inshade.codegen.targets import target as find_target

    if not isinstance(bundle, Bundle):
        bundle = load(bundle)
    parts = [np.asarray(a, np.float32) for a in (inputs if isinstance(inputs, (tuple, list)) else [inputs])]
    if len(parts) == 1 and len(bundle.inputs) > 1:
        parts = per_input(bundle, parts[0])
    x = np.concatenate([p.reshape(len(p), -1) for p in parts], 1)
    if shapes is not None:
        parts = [p.reshape(len(p), *shape) for p, shape in zip(parts, shapes)]
    start = time.perf_counter()
    ref = source_outputs(source, parts, bundle)
    glsl, renderer, storage = evaluate(bundle, x, storage=storage, ctx=ctx, limits=limits, generated=generated,
                                       target=target)
    result = compare(glsl, ref, renderer, storage, time.perf_counter() - start)
    return judge(dataclasses.replace(result, language=find_target(target).printer.language), source, parts,
                 bundle, glsl, ref)


def per_input(bundle, x: np.ndarray) -> list[np.ndarray]:
    """Concatenated inputs [N, in_dim] split into one array per bundle input."""
    bounds = np.cumsum([0, *(p.dim for p in bundle.inputs)])
    return [x[:, a:b] for a, b in zip(bounds[:-1], bounds[1:])]


def judge(result: CheckResult, source, parts, bundle, glsl: np.ndarray, ref: np.ndarray,
          lanes=slice(None)) -> CheckResult:
    """``result`` as it stands when it meets the rule; else with the float64 answer's distances from
    the shader and from the source (``ref``), for the conditioning rule. ``lanes``: the outputs
    ``glsl`` and ``ref`` hold."""
    if result.ok:
        return result
    start = time.perf_counter()
    try:
        exact = source_outputs(source, parts, bundle, float64=True)[:, lanes]
    except Float64Unavailable as exc:
        return dataclasses.replace(result, f64_missing=str(exc))
    return dataclasses.replace(result, glsl_f64=float(np.max(scaled_errors(glsl, exact), initial=0.0)),
                               source_f64=float(np.max(scaled_errors(ref, exact), initial=0.0)),
                               seconds=result.seconds + time.perf_counter() - start)


def source_outputs(source, parts: list[np.ndarray], bundle, float64: bool = False) -> np.ndarray:
    """The source's outputs on ``parts``, flattened per row and concatenated in output order;
    ``float64``: the source evaluated in double precision (its weights widened exactly)."""
    if _is_onnx(source):
        from .onnx_reference import run_onnxruntime

        outs = run_onnxruntime(source, parts, bundle, float64=float64)
    else:
        outs = _torch_outputs(source, parts, float64)
    return np.concatenate([np.asarray(o, np.float64 if float64 else np.float32).reshape(len(o), -1) for o in outs], 1)


def _torch_outputs(module, parts, float64: bool) -> list:
    import copy

    import torch

    dtype = torch.float64 if float64 else torch.float32
    if float64:
        module = copy.deepcopy(module).to(torch.float64)
    try:
        with torch.no_grad():
            result = module(*[torch.from_numpy(p).to(dtype) for p in parts])
    except RuntimeError as exc:   # e.g. a float32 tensor the module makes itself meets a float64 one
        if not float64:
            raise
        raise Float64Unavailable(f"the module in float64: {str(exc).splitlines()[0][:100]}") from None
    return [r.detach().cpu().numpy() for r in _flat_outputs(result)]


def _is_onnx(source) -> bool:
    from pathlib import Path

    if isinstance(source, (str, Path)):
        return True
    return type(source).__name__ == "ModelProto"


def _flat_outputs(result) -> list:
    if isinstance(result, dict):
        return list(result.values())
    if isinstance(result, (tuple, list)):
        return [r for item in result for r in _flat_outputs(item)]
    return [result]
