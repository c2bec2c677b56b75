"""A network at a lower precision, checked twice: the shader against the bundle's torch twin (the
dequantized weights, under the parity rule, as every check) and the twin against the fp32 source (the
quantization's own error, reported beside it), plus ``--max-error``: the cheapest precision per layer
whose error on the example stays within a bound, with the plan saying what it chose and why."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from inshade.quantize import EIGHT_BIT_FORMS, PRECISIONS, QUANTIZED_TYPES, lower_tables, quantized, weight_bytes


def twin(bundle):
    """The bundle's torch twin as a check's source: called on the check's inputs (one array per bundle
    input, any leading shape), its outputs [N, out_dim]."""
    import torch

    from inshade.models import GraphModule

    graph = GraphModule.from_bundle(bundle).eval()

    class Twin(torch.nn.Module):
        def forward(self, *parts):
            return graph(*(p.reshape(len(p), -1) for p in parts))

    return Twin()


@dataclass(frozen=True)
class Quantization:
    """The quantized network's twin against its fp32 source on the check's inputs."""
    precision: str
    max_abs: float
    psnr: float       # dB, peak = the source's output range
    bytes: int        # the dense weights' bytes at this precision
    fp32_bytes: int
    reference: str = "source"   # what the twin is held to: the source, or the fp32 network's twin

    def line(self) -> str:
        return (f"quantization ({self.precision}, dense weights {self.bytes} B, fp32 {self.fp32_bytes} B): "
                f"max |twin - {self.reference}| = {self.max_abs:.2g}, PSNR {self.psnr:.1f} dB on the example")

    def record(self) -> dict:
        return {"precision": self.precision, "max_abs": self.max_abs, "psnr": self.psnr, "bytes": self.bytes,
                "fp32_bytes": self.fp32_bytes}


def psnr(a: np.ndarray, ref: np.ndarray) -> float:
    """PSNR (dB) of ``a`` against ``ref``, the peak being ref's range (inf where equal)."""
    a, ref = np.asarray(a, np.float64), np.asarray(ref, np.float64)
    mse = float(np.mean((a - ref) ** 2))
    peak = max(float(ref.max() - ref.min()), 1e-30)
    return float("inf") if mse == 0 else 10.0 * np.log10(peak * peak / mse)


def quantization(source, bundle, fp32_bundle, parts, precision_name: str, reference: str = "source") -> Quantization:
    """``bundle`` (quantized from ``fp32_bundle``) against ``source`` (named ``reference``) on ``parts``
    (the check's inputs)."""
    from .check import source_outputs

    ref = source_outputs(source, parts, bundle)
    got = source_outputs(twin(bundle), parts, bundle)
    return Quantization(precision_name, float(np.abs(got - ref).max()), psnr(got, ref), weight_bytes(bundle),
                        weight_bytes(fp32_bundle), reference)


def describe(precision) -> str:
    """A precision as the plan and the check name it: "f16", or "l0 i8, l1 f16, ..." per layer."""
    if isinstance(precision, str):
        return precision
    return ", ".join(f"{k} {v}" for k, v in precision.items())


def _size(bundle, node) -> int:
    """The values a dense layer's weights or a table hold."""
    slots = ["weight"] if node.type in QUANTIZED_TYPES else EIGHT_BIT_FORMS[node.type][1](node.params)
    return int(sum(bundle.tensor(node, slot).size for slot in slots))


def _what(bundle, node) -> str:
    if node.type in QUANTIZED_TYPES:
        return f"{node.id} ({bundle.tensor(node, 'weight').shape[1]} -> {node.out_dim})"
    return f"{node.id} ({node.type}, {_size(bundle, node)} values)"


def choose(bundle, source, parts, max_error: float) -> tuple[dict, list[str]]:
    """The cheapest precision per dense layer and per table (i8, then f16, else as stored; a table's i8
    is its 8-bit form) whose network keeps max |twin - source| within ``max_error`` on ``parts``: the
    largest are tried first, each with the others at what was chosen so far. Returns ({node id:
    precision}, one line per layer or table saying why)."""
    from .check import source_outputs

    ref = source_outputs(source, parts, bundle)
    layers = sorted([n for n in bundle.nodes if n.type in QUANTIZED_TYPES] + lower_tables(bundle),
                    key=lambda n: -_size(bundle, n))
    chosen = {n.id: "f32" for n in layers}
    fp32_error = float(np.abs(source_outputs(twin(bundle), parts, bundle) - ref).max())
    if fp32_error > max_error:
        raise ValueError(f"max error {max_error:g}: the fp32 network is already {fp32_error:.2g} from its source "
                         "on the example")
    why = {}
    for n in layers:
        tried = []
        for p in (q for q in PRECISIONS[::-1] if q != "f32"):   # i8, then f16
            error = float(np.abs(source_outputs(twin(quantized(bundle, {**chosen, n.id: p})), parts, bundle)
                                 - ref).max())
            tried.append(f"{p} {error:.2g}")
            if error <= max_error:
                chosen[n.id] = p
                break
        why[n.id] = f"{_what(bundle, n)}: {chosen[n.id]} (max error with {', '.join(tried)}; bound {max_error:g})"
    order = [n.id for n in bundle.nodes if n.id in chosen]
    return {k: chosen[k] for k in order}, [why[k] for k in order]
