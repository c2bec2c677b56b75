"""Parity the user sees: a bundle's generated GLSL, run through the GL driver, against the source
it came from (the user's torch module, or onnxruntime for an ONNX file), on the same inputs.

The rule is the parity suite's: |glsl - source| <= 1e-5 * max(1, |source|) elementwise
(tests/parity.py). ``check`` returns the numbers; ``CheckResult.line()`` is what export and
convert print, e.g. ``max |glsl - source| = 3.1e-07 (rule 1e-05): ok``.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

RULE = 1e-5
RANDOM_ROWS = 1024


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

    @property
    def ok(self) -> bool:
        return bool(self.max_scaled <= self.rule)

    def line(self) -> str:
        verdict = "ok" if self.ok else f"FAILED at row {self.worst[0]}, output lane {self.worst[1]}"
        return f"max |glsl - source| = {self.max_scaled:.2g} (rule {self.rule:g}): {verdict}"

    def record(self) -> dict:
        """What a bundle's provenance keeps of the check."""
        return {"max_abs": self.max_abs, "max_scaled": self.max_scaled, "rule": self.rule, "ok": self.ok,
                "rows": self.rows, "gl_renderer": self.gl_renderer, "storage": self.storage}


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


def evaluate(bundle, inputs: np.ndarray, *, storage: str = "auto", ctx=None, limits=None, lut_filter: str = "exact"):
    """(outputs [N, out_dim] of the bundle's GLSL through the driver, GL_RENDERER, storage used);
    the GLSL planned against ``limits`` (default: the driver's)."""
    from inshade.codegen import generate
    from inshade.runtime.context import gl_info, shared_context
    from inshade.runtime.network import NetworkEvaluator

    ctx = shared_context() if ctx is None else ctx
    generated = generate(bundle, storage=storage, lut_filter=lut_filter, limits=gl_info(ctx) if limits is None else limits)
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


def check(source, bundle, inputs, *, storage: str = "auto", ctx=None, shapes=None, limits=None) -> CheckResult:
    """Run ``bundle``'s GLSL on ``inputs`` ([N, in_dim] concatenated, or a tuple of arrays, one per
    input) and compare with ``source``: a torch module (called on the inputs split per bundle
    input, each reshaped to [N, *shape] when ``shapes`` gives one per input) or an ONNX file path /
    ModelProto (onnxruntime)."""
    from inshade.bundle import Bundle, load

    if not isinstance(bundle, Bundle):
        bundle = load(bundle)
    parts = [np.asarray(a, np.float32) for a in (inputs if isinstance(inputs, (tuple, list)) else [inputs])]
    if len(parts) == 1 and len(bundle.inputs) > 1:
        bounds = np.cumsum([0, *(p.dim for p in bundle.inputs)])
        parts = [parts[0][:, a:b] for a, b in zip(bounds[:-1], bounds[1:])]
    x = np.concatenate([p.reshape(len(p), -1) for p in parts], 1)
    if shapes is not None:
        parts = [p.reshape(len(p), *shape) for p, shape in zip(parts, shapes)]
    start = time.perf_counter()
    ref = source_outputs(source, parts, bundle)
    glsl, renderer, storage = evaluate(bundle, x, storage=storage, ctx=ctx, limits=limits)
    return compare(glsl, ref, renderer, storage, time.perf_counter() - start)


def source_outputs(source, parts: list[np.ndarray], bundle) -> np.ndarray:
    """The source's outputs on ``parts``, flattened per row and concatenated in output order."""
    if _is_onnx(source):
        from .onnx_model import run_onnxruntime

        outs = run_onnxruntime(source, parts, bundle)
    else:
        import torch

        with torch.no_grad():
            result = source(*[torch.from_numpy(p) for p in parts])
        outs = [r.detach().cpu().float().numpy() for r in _flat_outputs(result)]
    return np.concatenate([o.reshape(len(o), -1) for o in outs], 1)


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
