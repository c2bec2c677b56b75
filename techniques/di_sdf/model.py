"""DI-SDF model: the cascade's sizing, the bundle graph, its sphere-tracing settings, the bound on
the hardware-filtered path's error, and the torch scene of an exported bundle.

    3D primary array (N_p³ × 3 channels, identity ramp, triangle F, 8-bit)
      -> 3D cascaded array (N_c³ × 1 channel: truncated distance, 8-bit)

The bundle graph is ``q -> to_unit -> primary -> cascaded``: ``q = (p - center) / radius`` is the
network-SDF contract (models/network_sdf.py, codegen/network_sdf.py: the graph sees the bound
sphere's unit ball, its output times ``radius`` is the world distance) and ``to_unit`` is a fixed
dense node ``0.5 q + 0.5`` that maps the cube [-1, 1]³ around that ball to the arrays' [0, 1]³.

Truncation (the band is ``truncation`` = τ, in normalised units, i.e. a fraction of the bound
radius; default 0.1): the target is ``clamp(d / radius, -τ, τ)``. The paper truncates to ±1 (a
sign field: only the zero crossing is learned); a linear band of a few primary cells keeps what a
sphere tracer and central-difference normals need -- distances near the surface -- and is the
paper's choice in the limit τ -> 0. After training the cascaded cells are clamped to [-τ, τ], so
every interpolated distance lies in the band too: the tracer (lib/sdf.glsl ``sdf_hit``) then
never steps more than ``τ · radius · step_scale``, i.e. its step is ``min(d, τ) · step_scale``
by construction, and stays inside the bound sphere. Far from the surface the field is flat at
+τ (steps of τ, ~2/τ of them across the bound), so ``max_steps`` is sized from τ (``trace_settings``).
"""
from __future__ import annotations

import math

import numpy as np
import torch

from inshade.components.dense.torch_twin import Dense
from inshade.models import indirection as di
from inshade.models.graph import GraphModule
from inshade.models.network_sdf import NetworkSdfModule

from .data import DiSdfError, Frame

RHO = 2.0                   # N_p / N_c: the middle of the paper's [1.5, 2.5] for SDFs
ALBEDO = (0.8, 0.8, 0.8)


def plan(budget_bytes: float, rho: float = RHO) -> di.Sizing:
    """Largest 8-bit 3D/3ch -> 3D/1ch cascade within the budget (N_p multiple of 8, N_c of 4)."""
    try:
        return di.size_cascade(int(budget_bytes), float(rho), primary_dims=3, primary_channels=3,
                               cascaded_dims=3, cascaded_channels=1)
    except ValueError as e:
        raise DiSdfError(f"--budget-kb {budget_bytes / 1024:g}: {e}") from None


def to_unit_node() -> Dense:
    """Fixed affine q in [-1, 1]^3 -> x = 0.5 q + 0.5 in [0, 1]^3 (exact in float32)."""
    d = Dense(3, 3, bias=True)
    with torch.no_grad():
        d.linear.weight.copy_(torch.eye(3) * 0.5)
        d.linear.bias.fill_(0.5)
    return d


def export_graph(core: GraphModule) -> GraphModule:
    """The bundle graph q -> to_unit -> primary -> cascaded (the trained arrays, shared)."""
    g = GraphModule([("q", 3, "position")])
    g.add("to_unit", to_unit_node(), "q")
    g.add("primary", core.nodes["primary"], "to_unit")
    g.add("cascaded", core.nodes["cascaded"], "primary")
    g.output("distance", "cascaded", "sdf")
    for p in g.parameters():
        p.requires_grad_(False)
    return g


def trace_settings(frame: Frame, truncation: float, n_primary: int, step_scale: float = 0.8) -> dict:
    """Sphere tracing for a truncated field. Steps are at most τ·radius·step_scale; crossing the
    bound (diameter 2 radius) flat at +τ takes 2 / (τ step_scale) steps, plus 48 to converge (grazing
    rays approach slowly). hit_eps: a twentieth of a primary cell; normal_eps: half a primary cell (the
    field is trilinear per cell: a smaller step sees cell facets, a larger one blurs detail)."""
    cell = 2.0 / (n_primary - 1) * frame.radius
    return {"max_steps": int(min(1024, math.ceil(2.0 / (truncation * step_scale)) + 48)),
            "step_scale": step_scale, "hit_eps": 0.05 * cell, "normal_eps": 0.5 * cell}


def fast_path_bound(bundle) -> float:
    """World-space bound on |fast - exact| of ``scene_sdf`` (hardware-filtered lookups): the
    lookup-array bound of tests/components/test_lookup_array.py, ``3 * 2^-8 * D + 2^-9 * scale`` per 3D array
    (D its largest adjacent-cell difference), with the primary's error e_k on channel k carried
    through the cascaded array's slope along axis k, ``D_c * (N_c - 1)``:

        e = 3 * 2^-8 * D_c + 2^-9 * s_c + sum_k D_c * (N_c - 1) * (3 * 2^-8 * D_p,k + 2^-9 * s_p,k)

    times the bound radius."""
    from inshade.bundle import Bundle

    g = GraphModule.from_bundle(Bundle(bundle.meta, bundle.tensors))
    tp = g.nodes["primary"].table().detach().double().numpy()
    tc = g.nodes["cascaded"].table().detach().double().numpy()
    d_p = np.array([max(float(np.abs(np.diff(tp[..., k], axis=a)).max()) for a in range(3)) for k in range(3)])
    d_c = max(float(np.abs(np.diff(tc[..., 0], axis=a)).max()) for a in range(3))
    s_p = bundle.tensors["primary.scale"].astype(np.float64)
    (s_c,) = bundle.tensors["cascaded.scale"].astype(np.float64)
    n_c = bundle.node("cascaded").params["resolution"][0]
    e_p = 3 * 2.0 ** -8 * d_p + 2.0 ** -9 * s_p
    e = 3 * 2.0 ** -8 * d_c + 2.0 ** -9 * s_c + float(np.sum(d_c * (n_c - 1) * e_p))
    return e * float(bundle.meta["render"]["sdf"]["radius"])


def sdf_module(bundle) -> NetworkSdfModule:
    """The torch scene of an exported DI-SDF bundle (trace/center/radius from render.sdf)."""
    return NetworkSdfModule.from_bundle(bundle)

