"""How far float16 arithmetic may take a network's shader from its float32 twin: a bound per example
and output, walked through the graph beside the twin's own values (float64).

The rule of a dense layer computed in float16 (codegen option ``arithmetic``; its weights and biases
are float16 values, so none is rounded on the way in), with u = 2^-11 float16's unit roundoff and
eta = 2^-25 the absolute error of a result rounded below float16's normal range:

- each input x (the twin's value, within e of it on the shader) is rounded to float16:
  |x' - x| <= r = e + u (|x| + e) + eta;
- the n = in + 1 products and sums in float16, in whatever order and with or without fused
  multiply-adds: |error| <= gamma_n S + 2 n eta, gamma_n = n u / (1 - n u), S = sum_j |w_j| (|x_j| + r_j) + |b|
  (the classic bound of a dot product, Higham 2002, 3.1); ``f16_acc32`` (each mat4 block's product
  in float16, the blocks summed in float32): gamma_min(4,n) S + gamma_n(2^-24) S + n eta;
- so |y' - y| <= sum_j |w_j| r_j + that; past float16's largest value (65504) S may overflow: the
  bound is infinite there.

A float32 dense layer passes the error on (|W| e); an elementwise activation by its change over the
interval [v - e, v + e] (sampled: the activations are monotone or smooth at this scale); a lookup array
by its steepest slope per coordinate (``_lookup_slopes``); ``add``, ``affine`` and ``select`` as their
arithmetic says. A component without a rule refuses an input that
carries error. The shader is held to the bound plus the float32 rule (1e-5) against the twin.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from inshade.components.spec import COMPONENTS

U16 = 2.0 ** -11
ETA16 = 2.0 ** -25
U32 = 2.0 ** -24
HALF_MAX = 65504.0
SAMPLES = 9   # points of [v - e, v + e] an activation is evaluated at
RULE = 1e-5   # the float32 rule, on top of the bound (the twin is float32 too)


def gamma(n: int, u: float) -> float:
    return n * u / (1.0 - n * u)


def _dense(bundle, node, v, e, arithmetic: str):
    aw = torch.from_numpy(np.abs(np.asarray(bundle.tensor(node, "weight"), np.float64)))
    b = torch.from_numpy(np.asarray(bundle.tensor(node, "bias"), np.float64)) if node.params["bias"] else 0.0
    if arithmetic == "f32":
        return e @ aw.T
    r = e + U16 * (v.abs() + e) + ETA16
    s = (v.abs() + r) @ aw.T + abs(b)
    n = aw.shape[1] + 1
    rounding = (gamma(n, U16) * s + 2 * n * ETA16 if arithmetic == "f16"
                else gamma(min(4, n), U16) * s + gamma(n, U32) * s + n * ETA16)
    bound = r @ aw.T + rounding
    return torch.where(s > HALF_MAX, torch.full_like(bound, float("inf")), bound)


def _activation(comp, v, e):
    t = torch.linspace(-1.0, 1.0, SAMPLES, dtype=torch.float64)
    y = comp(v)
    moved = torch.stack([(comp(v + k * e) - y).abs() for k in t]).max(0).values
    return torch.nan_to_num(moved, nan=float("inf"))   # an argument out of the domain within e: unbounded


def _lookup_slopes(comp, resolution) -> torch.Tensor:
    """[dims, channels]: how fast a lookup array's output can change per unit of each coordinate lane,
    (N_d - 1) times the largest difference of neighbouring cells along that axis (a multilinear
    interpolation changes no faster anywhere; clamping to [0, 1] only slows it)."""
    table = comp.table().detach().double()
    dims, channels = len(resolution), table.shape[-1]
    rows = []
    for d, n in enumerate(resolution):   # lane d indexes axis dims - 1 - d (cells are [N_{d-1}, ..., N_0, C])
        step = table.diff(dim=dims - 1 - d).abs().reshape(-1, channels) if n > 1 else torch.zeros(1, channels,
                                                                                                   dtype=torch.float64)
        rows.append((n - 1) * step.amax(0))
    return torch.stack(rows)


def _rule(bundle, node, comp, v, e, arithmetic: str):
    """The error bound of ``node``'s output from its input's (``v``: the twin's input values, ``e``: their bound)."""
    if node.type == "dense":
        return _dense(bundle, node, v, e, arithmetic)
    if not bool((e > 0).any()):
        return torch.zeros_like(comp(v))   # computed in float32 from exact inputs: the float32 rule's
    if node.type == "add":
        half = e.shape[-1] // 2
        return e[..., :half] + e[..., half:]
    if node.type == "affine":
        return e * torch.as_tensor(np.abs(np.asarray(node.params["scale"], np.float64)), dtype=torch.float64)
    if node.type == "select":
        return e[..., list(node.params["lanes"])]
    if node.type == "lookup_array":
        return e @ _lookup_slopes(comp, node.params["resolution"])
    if COMPONENTS[node.type].category == "activation":   # lane-wise
        return _activation(comp, v, e)
    raise ValueError(f"node {node.id}: component {node.type!r} has no float16 error rule, and its input comes "
                     "from a layer computed in float16; compute the network in float32 there")


def half_envelope(bundle, x: np.ndarray, arithmetic: str) -> tuple[np.ndarray, np.ndarray]:
    """(the float64 twin's outputs [N, out], the bound [N, out] of |shader - twin| where the dense layers
    compute at ``arithmetic``: "f32", "f16" or "f16_acc32")."""
    from inshade.models import GraphModule

    module = GraphModule.from_bundle(bundle).double()
    by_id = {n.id: n for n in bundle.nodes}
    xs = torch.from_numpy(np.asarray(x, np.float64))
    values, errors, off = {}, {}, 0
    with torch.no_grad():
        for name, dim, _ in module.inputs:
            values[name], off = xs[..., off:off + dim], off + dim
            errors[name] = torch.zeros_like(values[name])
        for node_id, comp in module.nodes.items():
            srcs = module.wiring[node_id]
            v = torch.cat([values[s] for s in srcs], -1)
            e = torch.cat([errors[s] for s in srcs], -1)
            values[node_id], errors[node_id] = comp(v), _rule(bundle, by_id[node_id], comp, v, e, arithmetic)
        out = [values[node] for _, node, _ in module.outputs]
        bound = [errors[node] for _, node, _ in module.outputs]
    return torch.cat(out, -1).numpy(), torch.cat(bound, -1).numpy()


@dataclass(frozen=True)
class HalfCheck:
    """A float16 program against its twin under the envelope (``inshade codegen --check``)."""
    max_abs: float        # max |shader - twin|
    max_bound: float      # the largest finite bound
    outside: int          # outputs outside bound + the float32 rule
    unbounded: int        # outputs whose bound is infinite (float16 may overflow there)
    worst: tuple          # (row, lane) of the largest error relative to its allowance
    rows: int
    gl_renderer: str
    language: str

    @property
    def ok(self) -> bool:
        return self.outside == 0

    def line(self) -> str:
        verdict = "ok" if self.ok else (f"FAILED: {self.outside} outputs outside, the worst at row {self.worst[0]}, "
                                        f"output lane {self.worst[1]}")
        unbounded = f"; {self.unbounded} outputs unbounded (float16 overflow possible)" if self.unbounded else ""
        return (f"max |{self.language} - twin| = {self.max_abs:.2g} within the float16 envelope (bound up to "
                f"{self.max_bound:.2g} per output, + {RULE:g}){unbounded}: {verdict}")


def check_half(bundle, generated, x: np.ndarray, target: str, arithmetic: str) -> HalfCheck:
    """The program ``generated`` (float16 arithmetic, for ``target``) on the compute device against the
    bundle's twin under the envelope."""
    from inshade.codegen.targets import target as find_target
    from inshade.runtime.compute import compute_device, run_target

    twin, bound = half_envelope(bundle, x, arithmetic)
    out = run_target(generated, x, target)[0].astype(np.float64)
    err = np.abs(out - twin)
    finite = np.isfinite(bound)
    allowance = np.where(finite, bound, np.inf) + RULE
    over = finite & ~(err <= allowance)
    ratio = np.where(finite, err / allowance, 0.0)
    worst = np.unravel_index(int(np.nanargmax(np.nan_to_num(ratio, nan=np.inf))), ratio.shape)
    return HalfCheck(float(np.nanmax(err)), float(bound[finite].max()) if finite.any() else float("inf"),
                     int(over.sum()), int((~finite).sum()), tuple(int(i) for i in worst), len(x),
                     compute_device().description, find_target(target).printer.language)
