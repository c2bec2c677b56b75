"""Differentiable Indirection's lookup arrays: the bundle-level spec."""
from __future__ import annotations

import numpy as np

from inshade.components.spec import ComponentError, ComponentSpec, Param, TensorSpec, pos_int, register


MAX_LUT_CELLS = 1 << 28   # cells x channels of one lookup array
LUT_BITS = {8: "uint8", 16: "uint16", 32: "float32"}
LUT_BAKED = ("none", "triangle", "sinusoid")
# the GLSL paths (codegen option lookup_array.filter, lut_filter for short): emit.py says what each does
FILTERS = ("exact", "fast")


def _lut_tensors(p, d):
    shape = tuple(reversed(p["resolution"])) + (p["channels"],)
    out = {"cells": TensorSpec(shape, LUT_BITS[p["bits"]])}
    if p["bits"] != 32:
        out["scale"] = TensorSpec((p["channels"],), "float32")
        out["offset"] = TensorSpec((p["channels"],), "float32")
    return out


def _lut_checks(p, d):
    res = p["resolution"]
    if not (isinstance(res, list) and 1 <= len(res) <= 4 and all(pos_int(1 << 16)(n) for n in res)):
        raise ComponentError("resolution must be a list of 1 to 4 positive ints")
    if len(res) != d:
        raise ComponentError(f"a {len(res)}D lookup array needs a {len(res)}-wide input, got {d}")
    if int(np.prod(res)) * p["channels"] > MAX_LUT_CELLS:
        raise ComponentError(f"lookup array of {res} x {p['channels']} cells is absurdly large")


register(ComponentSpec(
    "lookup_array",
    "Differentiable Indirection array: corner-aligned multilinear lookup of cells "
    "[N_{d-1},...,N_0, C]; input clamped to [0,1]; cells = offset + scale * q / (2^bits - 1) "
    "when quantised; the periodic non-linearity is already baked into the cells",
    {"resolution": Param(list), "channels": Param(int, check=pos_int(64)),
     "bits": Param(int, check=lambda v: v in LUT_BITS),
     "baked": Param(str, "none", lambda v: v in LUT_BAKED)},
    out_dim=lambda p, d: p["channels"],
    tensors=_lut_tensors,
    category="lookup",
    extra_checks=_lut_checks,
))
