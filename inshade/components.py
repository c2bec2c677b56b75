"""Component types of the bundle graph: parameters, output width and tensor shapes.

This is the numpy-level description every executor shares. The torch reference
(`inshade.models`) and the GLSL emitters (`inshade.codegen`) register classes under the
same type names; this module only says what a well-formed node of each type looks like.

New techniques (latent texture pyramids, hashed feature tables, voxel latents) arrive as
new entries in COMPONENTS, not as a new bundle format.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from .grid_layout import MAX_DENSE_RESOLUTION, GridLayoutError, grid_levels, table_rows

MAX_WIDTH = 4096          # widest dense layer a bundle may declare
MAX_LUT_CELLS = 1 << 28   # cells x channels of one lookup array
MAX_FREQS = 16
SH_MAX_DEGREE = 5         # bands l = 0..4, i.e. "up to order 4"


class ComponentError(ValueError):
    """A node's parameters or inputs do not describe a valid component."""


@dataclass(frozen=True)
class Param:
    kind: type | tuple
    default: Any = ...
    check: Callable[[Any], bool] | None = None
    doc: str = ""


@dataclass(frozen=True)
class TensorSpec:
    shape: tuple[int, ...]
    dtype: str  # numpy dtype name
    # values must survive a round trip through this dtype (e.g. "float16" for latents stored in
    # RGBA16F textures): the bundle then holds exactly what the GPU will see
    representable: str | None = None


@dataclass(frozen=True)
class ComponentSpec:
    type: str
    doc: str
    params: dict[str, Param]
    out_dim: Callable[[dict, int], int]
    tensors: Callable[[dict, int], dict[str, TensorSpec]] = lambda p, d: {}
    in_dim: Callable[[dict, int], bool] | None = None   # accepts input width?
    category: str = "activation"
    extra_checks: Callable[[dict, int], None] | None = None
    tags: tuple[str, ...] = field(default_factory=tuple)


def _pos_int(limit):
    return lambda v: isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= limit


def _finite(v):
    return np.isfinite(float(v))


def _same(p, d):
    return d


def _float32(v) -> np.float32:
    """v as the float32 both executors compute with (inf beyond float32's range)."""
    with np.errstate(over="ignore"):
        return np.float32(v)


def _finite32(v):
    return bool(np.isfinite(_float32(v)))


ACTIVATIONS = ("relu", "leaky_relu", "sigmoid", "tanh", "softplus", "sin", "cos", "exp", "expm1", "identity",
               "silu", "gelu", "elu", "abs", "clamp", "erf")
# elementwise too, but defined on part of the line only (x >= 0, x != 0, x > 0; power: x >= 0 for a
# non-integer exponent, x != 0 for a negative one): random MLP generators must not feed them
PARTIAL_ELEMENTWISE = ("sqrt", "reciprocal", "log", "log2", "power")
# elementwise and exact (bit-identical on both sides for the same input), but stepped: at integers
# (half-integers for round) or multiples of the divisor, where a computed argument one ulp across
# moves the output by the whole step; not for random MLPs either
STEPPED_ELEMENTWISE = ("floor", "ceil", "trunc", "round", "frac", "fmod", "remainder")
GELU_FORMS = ("none", "tanh")

COMPONENTS: dict[str, ComponentSpec] = {}


def _register(spec: ComponentSpec) -> None:
    COMPONENTS[spec.type] = spec


_register(ComponentSpec(
    "dense", "y = W x + b, W stored [out, in] like torch.nn.Linear",
    {"out": Param(int, check=_pos_int(MAX_WIDTH)), "bias": Param(bool, True)},
    out_dim=lambda p, d: p["out"],
    tensors=lambda p, d: {"weight": TensorSpec((p["out"], d), "float32"),
                          **({"bias": TensorSpec((p["out"],), "float32")} if p["bias"] else {})},
    in_dim=lambda p, d: 1 <= d <= MAX_WIDTH,
    category="layer",
))
for _name in ("relu", "sigmoid", "tanh", "exp", "expm1", "identity", "silu", "abs", "erf", "sqrt", "reciprocal"):
    _register(ComponentSpec(_name, f"elementwise {_name}", {}, out_dim=_same))
for _name, _doc in (
        ("log", "natural logarithm as torch.log: NaN below 0, -inf at +-0, +inf at +inf"),
        ("log2", "base-2 logarithm as torch.log2: NaN below 0, -inf at +-0, +inf at +inf"),
        ("floor", "largest integer <= x (torch.floor)"),
        ("ceil", "smallest integer >= x (torch.ceil)"),
        ("trunc", "x rounded toward 0 (torch.trunc)"),
        ("round", "x rounded to the nearest integer, halves to even as torch.round: 0.5 -> 0, 1.5 -> 2, -2.5 -> -2"),
        ("frac", "x - trunc(x) as torch.frac: the sign of x (not GLSL's fract, x - floor(x))")):
    _register(ComponentSpec(_name, _doc, {}, out_dim=_same))
_DIVISOR = Param(float, check=lambda v: _finite32(v) and abs(_float32(v)) >= np.finfo(np.float32).tiny,
                 doc="finite and normal in float32, |divisor| >= 2^-126 (both sides use it rounded to float32; "
                     "torch's fmod of a subnormal divisor is NaN)")
_register(ComponentSpec(
    "fmod", "torch.fmod(x, divisor), exact (C's fmod): x - n divisor, n = trunc(x / divisor), the sign of x, "
            "|result| < |divisor|; NaN for an infinite x", {"divisor": _DIVISOR}, out_dim=_same))
_register(ComponentSpec(
    "remainder", "torch.remainder(x, divisor) (Python's %): fmod, plus divisor where that is non-zero and of the "
                 "other sign (one rounding: the result may equal the divisor, as torch's)",
    {"divisor": _DIVISOR}, out_dim=_same))
_register(ComponentSpec(
    "power", "torch.pow(x, exponent), exponent constant: torch's special cases (0, 1, 0.5, -0.5, -1) and C's pow "
             "(x < 0: NaN unless the exponent is an integer, signed for an odd one; x = 0: 0 or +-inf)",
    {"exponent": Param(float, check=_finite32, doc="finite in float32 (both sides use it rounded to float32)")},
    out_dim=_same))
_register(ComponentSpec("leaky_relu", "x if x>0 else slope*x",
                        {"slope": Param(float, 0.01, _finite)}, out_dim=_same))
_register(ComponentSpec("sin", "sin(omega0 * x), SIREN's activation",
                        {"omega0": Param(float, 1.0, _finite)}, out_dim=_same))
_register(ComponentSpec("cos", "cos(omega0 * x)", {"omega0": Param(float, 1.0, _finite)}, out_dim=_same))
_register(ComponentSpec(
    "softplus", "log(1 + exp(beta x)) / beta; x where beta x > threshold (absent: no threshold)",
    {"beta": Param(float, 1.0, lambda v: _finite(v) and v > 0, "finite and > 0"),
     "threshold": Param(float, None, _finite, "finite")}, out_dim=_same))
_register(ComponentSpec("gelu", "x * Phi(x), Phi by erf ('none') or torch's tanh approximation ('tanh')",
                        {"approximate": Param(str, "none", lambda v: v in GELU_FORMS, " or ".join(GELU_FORMS))},
                        out_dim=_same))
_register(ComponentSpec("elu", "x if x > 0 else alpha (exp(x) - 1)", {"alpha": Param(float, 1.0, _finite)},
                        out_dim=_same))
_register(ComponentSpec("clamp", "min(max(x, min), max); either bound may be absent",
                        {"min": Param(float, None, _finite, "finite"), "max": Param(float, None, _finite, "finite")},
                        out_dim=_same, extra_checks=lambda p, d: _ordered(p)))


def _ordered(p):
    if p["min"] is None and p["max"] is None:
        raise ComponentError("clamp: needs min, max or both")
    if p["min"] is not None and p["max"] is not None and p["min"] > p["max"]:
        raise ComponentError(f"clamp: min {p['min']} > max {p['max']}")


# --- the feature axis: constants, lane selection, branches, reductions, normalisation ----------

_register(ComponentSpec(
    "affine", "y = x * scale + offset, per lane (folded constants, BatchNorm in eval mode)",
    {}, out_dim=_same,
    tensors=lambda p, d: {"scale": TensorSpec((d,), "float32"), "offset": TensorSpec((d,), "float32")},
    category="layer",
))


def _lanes_check(p, d):
    bad = [i for i in p["lanes"] if not (isinstance(i, int) and not isinstance(i, bool) and 0 <= i < d)]
    if bad:
        raise ComponentError(f"select: lane {bad[0]!r} is not in 0..{d - 1}")


_register(ComponentSpec(
    "select", "y = x[lanes]: lanes of the input in any order, repeats allowed (slices, splits, broadcasts)",
    {"lanes": Param(list, check=lambda v: 1 <= len(v) <= MAX_WIDTH, doc=f"1..{MAX_WIDTH} lane indices")},
    out_dim=lambda p, d: len(p["lanes"]), extra_checks=_lanes_check, category="layer",
))
for _name, _expr in (("sub", "a - b"), ("mul", "a * b"), ("div", "a / b"),
                     ("atan2", "atan2(a, b) as torch.atan2(a, b): the angle of the point (x = b, y = a), C's "
                               "special values (atan2(+-0, -0) = +-pi, atan2(+-0, +0) = +-0)")):
    _register(ComponentSpec(
        _name, f"two branches: input [a (n lanes), b (n lanes)] -> {_expr} (n lanes)", {},
        out_dim=lambda p, d: d // 2, in_dim=lambda p, d: d >= 2 and d % 2 == 0, category="layer"))

# integer lanes: uint32 arithmetic, wrapping modulo 2^32 (torch's int64 agrees on every result
# whose true value lies in 0..2^32-1, which is what a table index must be)
INT_OPS = {"lane": 1, "const": 1, "add": 2, "sub": 2, "mul": 2, "xor": 2, "and": 2, "or": 2, "shl": 2}
MAX_INT_PROGRAM = 4096
MAX_GATHER_ROWS = 1 << 26


def _int_gather_checks(p, d):
    prog = p["program"]
    for k, op in enumerate(prog):
        if not (isinstance(op, list) and op and op[0] in INT_OPS and len(op) == 1 + INT_OPS[op[0]]
                and all(isinstance(a, int) and not isinstance(a, bool) for a in op[1:])):
            raise ComponentError(f"program[{k}]: {op!r} is not [op, arg...] with op one of {', '.join(INT_OPS)}")
        name, args = op[0], op[1:]
        if name == "lane" and not 0 <= args[0] < d:
            raise ComponentError(f"program[{k}]: lane {args[0]} is not in 0..{d - 1}")
        if name == "const" and not 0 <= args[0] < 1 << 32:
            raise ComponentError(f"program[{k}]: constant {args[0]} is not a uint32")
        if name == "shl" and not (0 <= args[0] < k and 0 <= args[1] < 32):
            raise ComponentError(f"program[{k}]: shl takes an earlier entry and a shift in 0..31")
        if name not in ("lane", "const", "shl") and not all(0 <= a < k for a in args):
            raise ComponentError(f"program[{k}]: {name} must refer to earlier entries")
    bad = [i for i in p["indices"] if not (isinstance(i, int) and 0 <= i < len(prog))]
    if bad:
        raise ComponentError(f"indices: {bad[0]!r} is not an entry of the program")


_register(ComponentSpec(
    "int_gather",
    "rows of a learned table at computed integer indices: each program entry is a uint32 "
    "(['lane', k]: input lane k truncated toward 0, as torch's float -> int cast; ['const', c]; "
    "add, sub, mul, xor, and, or of two earlier entries, shl of an entry by a constant: all modulo 2^32); "
    "output = table[entry] for each entry in indices, concatenated (zeros where an index is >= the "
    "table's rows)",
    {"program": Param(list, check=lambda v: 1 <= len(v) <= MAX_INT_PROGRAM,
                      doc=f"1..{MAX_INT_PROGRAM} entries"),
     "indices": Param(list, check=lambda v: 1 <= len(v) <= MAX_WIDTH, doc="program entries used as row indices"),
     "rows": Param(int, check=_pos_int(MAX_GATHER_ROWS)),
     "features": Param(int, check=_pos_int(MAX_WIDTH))},
    out_dim=lambda p, d: len(p["indices"]) * p["features"],
    tensors=lambda p, d: {"table": TensorSpec((p["rows"], p["features"]), "float32")},
    category="lookup", extra_checks=_int_gather_checks,
))

COMPARISONS = ("gt", "ge", "lt", "le")
_register(ComponentSpec(
    "where", "a comparison choosing between branches: input [a, b, x, y] (n lanes each) -> "
             "(a op b) ? x : y, op one of gt, ge, lt, le",
    {"op": Param(str, check=lambda v: v in COMPARISONS, doc=", ".join(COMPARISONS))},
    out_dim=lambda p, d: d // 4, in_dim=lambda p, d: d >= 4 and d % 4 == 0, category="layer",
))
REDUCE_OPS = ("sum", "mean", "norm", "max", "min")


def _groups_check(p, d):
    if d % p["groups"]:
        raise ComponentError(f"groups: {p['groups']} does not divide the input width {d}")


_register(ComponentSpec(
    "reduce", "the input as `groups` equal runs of lanes, each reduced to one lane by op "
              "(sum, mean, norm = sqrt of the sum of squares, max, min)",
    {"op": Param(str, check=lambda v: v in REDUCE_OPS, doc=", ".join(REDUCE_OPS)),
     "groups": Param(int, 1, _pos_int(MAX_WIDTH))},
    out_dim=lambda p, d: p["groups"], extra_checks=_groups_check, category="layer",
))
_register(ComponentSpec(
    "layer_norm", "LayerNorm of each of `groups` equal runs of lanes: (x - mean) / sqrt(var + eps), "
                  "biased variance; then * weight + bias per lane of a run when `affine`",
    {"eps": Param(float, 1e-5, lambda v: _finite(v) and v >= 0, "finite and >= 0"),
     "groups": Param(int, 1, _pos_int(MAX_WIDTH)), "affine": Param(bool, True)},
    out_dim=_same, extra_checks=_groups_check, category="layer",
    tensors=lambda p, d: ({"weight": TensorSpec((d // p["groups"],), "float32"),
                           "bias": TensorSpec((d // p["groups"],), "float32")} if p["affine"] else {}),
))

_register(ComponentSpec(
    "frequency", "NeRF positional encoding: [x] + [sin(2^k pi x), cos(2^k pi x)] for k < n_freqs",
    {"n_freqs": Param(int, check=_pos_int(MAX_FREQS)), "include_input": Param(bool, True)},
    out_dim=lambda p, d: d * (2 * p["n_freqs"] + (1 if p["include_input"] else 0)),
    category="encoding",
))
_register(ComponentSpec(
    "triangle_wave", "tri(2^k x) for k < n_freqs, tri(t) = 1 - |mod(t, 2) - 1|",
    {"n_freqs": Param(int, check=_pos_int(MAX_FREQS))},
    out_dim=lambda p, d: d * p["n_freqs"],
    category="encoding",
))
ONE_BLOB_MAX_BINS = 1024


def _one_blob_width(p, d):
    if d * p["n_bins"] > MAX_WIDTH:
        raise ComponentError(f"n_bins: {d} inputs x {p['n_bins']} bins = {d * p['n_bins']} lanes, more than {MAX_WIDTH}")


_register(ComponentSpec(
    "one_blob", "tiny-cuda-nn's OneBlob (encodings/oneblob.h, kernel_one_blob_soa): per input x and bin "
                "k < n_bins, the mass of a quartic kernel of radius 1/n_bins centred at x (wrapped with "
                "period 1) that falls in [k, k+1) / n_bins; lanes input-major (x_i's bins at i*n_bins..); "
                "models/encodings.py has the exact rule",
    {"n_bins": Param(int, 16, lambda v: _pos_int(ONE_BLOB_MAX_BINS)(v) and v & (v - 1) == 0,
                     doc=f"a power of two, 1..{ONE_BLOB_MAX_BINS}")},
    out_dim=lambda p, d: d * p["n_bins"],
    extra_checks=_one_blob_width,
    category="encoding",
))
_register(ComponentSpec(
    "spherical_harmonics", "real orthonormal SH basis of a unit direction, bands l < degree",
    {"degree": Param(int, check=_pos_int(SH_MAX_DEGREE))},
    out_dim=lambda p, d: p["degree"] ** 2,
    in_dim=lambda p, d: d == 3,
    category="encoding",
))

LUT_BITS = {8: "uint8", 16: "uint16", 32: "float32"}
LUT_BAKED = ("none", "triangle", "sinusoid")


def _lut_tensors(p, d):
    shape = tuple(reversed(p["resolution"])) + (p["channels"],)
    out = {"cells": TensorSpec(shape, LUT_BITS[p["bits"]])}
    if p["bits"] != 32:
        out["scale"] = TensorSpec((p["channels"],), "float32")
        out["offset"] = TensorSpec((p["channels"],), "float32")
    return out


def _lut_checks(p, d):
    res = p["resolution"]
    if not (isinstance(res, list) and 1 <= len(res) <= 4 and all(_pos_int(1 << 16)(n) for n in res)):
        raise ComponentError("resolution must be a list of 1 to 4 positive ints")
    if len(res) != d:
        raise ComponentError(f"a {len(res)}D lookup array needs a {len(res)}-wide input, got {d}")
    if int(np.prod(res)) * p["channels"] > MAX_LUT_CELLS:
        raise ComponentError(f"lookup array of {res} x {p['channels']} cells is absurdly large")


_register(ComponentSpec(
    "lookup_array",
    "Differentiable Indirection array: corner-aligned multilinear lookup of cells "
    "[N_{d-1},...,N_0, C]; input clamped to [0,1]; cells = offset + scale * q / (2^bits - 1) "
    "when quantised; the periodic non-linearity is already baked into the cells",
    {"resolution": Param(list), "channels": Param(int, check=_pos_int(64)),
     "bits": Param(int, check=lambda v: v in LUT_BITS),
     "baked": Param(str, "none", lambda v: v in LUT_BAKED)},
    out_dim=lambda p, d: p["channels"],
    tensors=_lut_tensors,
    category="lookup",
    extra_checks=_lut_checks,
))


# --- neural appearance (Real-Time Neural Appearance Models, NVIDIA 2024) ----------------------

LATENT_PRECISIONS = {"f16": "float16", "f32": None}
MAX_LATENT_RES = 1 << 14


def _is_pow2(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= MAX_LATENT_RES and v & (v - 1) == 0


def _pyramid_tensors(p, d):
    res, c = p["resolution"], p["channels"]
    rep = LATENT_PRECISIONS[p["precision"]]
    return {f"level{k}": TensorSpec((res >> k, res >> k, c), "float32", rep) for k in range(p["levels"])}


def _pyramid_checks(p, d):
    top = p["resolution"].bit_length()   # log2(res) + 1 levels down to 1x1
    if not 1 <= p["levels"] <= top:
        raise ComponentError(f"param 'levels' of latent_pyramid must be 1..{top} for resolution "
                             f"{p['resolution']}, got {p['levels']}")


_register(ComponentSpec(
    "latent_pyramid",
    "latent texture mip pyramid: input (u, v, level); level floored and clamped to [0, levels-1]; "
    "bilinear within that level, texel centres at (i + 0.5) / N, wrap = repeat; "
    "level k is [res >> k, res >> k, channels]",
    {"resolution": Param(int, check=_is_pow2, doc=f"a power of two, at most {MAX_LATENT_RES}"),
     "levels": Param(int, check=_pos_int(15)),
     "channels": Param(int, 8, lambda v: isinstance(v, int) and 4 <= v <= 64 and v % 4 == 0,
                       doc="a multiple of 4 from 4 to 64: one RGBA texture per 4"),
     "precision": Param(str, "f32", lambda v: v in LATENT_PRECISIONS)},
    out_dim=lambda p, d: p["channels"],
    tensors=_pyramid_tensors,
    in_dim=lambda p, d: d == 3,
    category="lookup",
    extra_checks=_pyramid_checks,
))
_register(ComponentSpec(
    "shading_frames",
    "learned shading frames (Eq. 7): input [z (latent), light (3), view (3)]; a linear layer "
    "[6N, latent] gives per frame k n_k = rows 6k..6k+2, t_k = rows 6k+3..6k+5; n, t normalised "
    "(not orthogonalised), b = normalize(n x t); output per frame (t.l, b.l, n.l, t.v, b.v, n.v)",
    {"frames": Param(int, 2, _pos_int(8)), "latent": Param(int, 8, _pos_int(64))},
    out_dim=lambda p, d: 6 * p["frames"],
    tensors=lambda p, d: {"weight": TensorSpec((6 * p["frames"], p["latent"]), "float32"),
                          "bias": TensorSpec((6 * p["frames"],), "float32")},
    in_dim=lambda p, d: d == p["latent"] + 6,
    category="layer",
))
PROXY_PARAMS = ("w_d", "w_s", "mu_d.x", "mu_d.y", "alpha_x", "alpha_y", "rho", "mu_s.x", "mu_s.y")
_register(ComponentSpec(
    "proxy_params",
    "importance-sampling proxy output activation: raw 9 lanes (3 when isotropic: 2 logits, alpha) "
    "-> [w_d, w_s, mu_d.x, mu_d.y, alpha_x, alpha_y, rho, mu_s.x, mu_s.y] (models/proxy_lobe.py)",
    {"isotropic": Param(bool, False),
     "alpha_min": Param(float, 0.01, lambda v: np.isfinite(v) and 0.0 < v <= 1.0)},
    out_dim=lambda p, d: len(PROXY_PARAMS),
    in_dim=lambda p, d: d == (3 if p["isotropic"] else 9),
))


# --- UV-free neural material (Walloner 2024; models/mesh_features.py has the exact rules) ------

MESH_FEATURE_PRECISIONS = {"f16": "float16", "f32": None, "u8": None}
MESH_FEATURE_STORAGE = {"f16": "float32", "f32": "float32", "u8": "uint8"}   # the table tensor's dtype

MESH_MAX_FACES = 1 << 24          # triangle ids travel through torch as exact float32 integers
MESH_MAX_TABLE = 1 << 24
MESH_MAX_VALUES = 1 << 28         # levels * table_size * features (1 GiB of float32)


def _mesh_feature_tensors(p, d):
    out = {"table": TensorSpec((p["levels"] * p["table_size"], p["features"]), MESH_FEATURE_STORAGE[p["precision"]],
                               MESH_FEATURE_PRECISIONS[p["precision"]]),
           "corners": TensorSpec((p["faces"], 3), "uint32"),
           "edges": TensorSpec((p["faces"], 3), "uint32")}
    if p["precision"] == "u8":   # per feature lane: value = offset + scale * q / 255
        out["scale"] = TensorSpec((p["features"],), "float32")
        out["offset"] = TensorSpec((p["features"],), "float32")
    return out


def _mesh_feature_checks(p, d):
    t, n = p["table_size"], p["faces"]
    if not (2 <= t <= MESH_MAX_TABLE and t & (t - 1) == 0):
        raise ComponentError(f"table_size: must be a power of two, got {t}")
    if not 1 <= n <= MESH_MAX_FACES:
        raise ComponentError(f"faces: must be 1..{MESH_MAX_FACES} (triangle ids travel as exact float32 "
                             f"integers), got {n}")
    if p["levels"] * t * p["features"] > MESH_MAX_VALUES:
        raise ComponentError(f"table_size: levels * table_size * features = {p['levels'] * t * p['features']} "
                             f"values, more than {MESH_MAX_VALUES}")


_register(ComponentSpec(
    "mesh_features",
    "UV-free hashed per-triangle feature hierarchy: input (triangle id, t0, t1); per level l a "
    "2^l subdivision, sub-vertices canonicalised by the corners/edges owner tables, hashed into "
    "table rows l*T..l*T+T-1, barycentric blend; output levels*features lanes; precision u8: the "
    "table is uint8 q with per-lane value = offset + scale * q / 255 (applied after the blend)",
    {"levels": Param(int, check=_pos_int(16)),
     "features": Param(int, 2, lambda v: v in (1, 2, 4, 8), doc="1, 2, 4 or 8"),
     "table_size": Param(int, doc="a power of two, 2..2^24"),
     "faces": Param(int, doc="1..2^24"),
     "precision": Param(str, "f16", lambda v: v in MESH_FEATURE_PRECISIONS, doc="f16, f32 or u8")},
    out_dim=lambda p, d: p["levels"] * p["features"],
    tensors=_mesh_feature_tensors,
    in_dim=lambda p, d: d == 3,
    category="lookup",
    extra_checks=_mesh_feature_checks,
))



# --- multiresolution grid encodings (instant-NGP; inshade/grid_layout.py has the rules) --------

GRID_PRECISIONS = {"f16": "float16", "f32": None}
GRID_KINDS = {"hash_grid": "hash", "dense_grid": "dense"}
MAX_GRID_ROWS = 1 << 26


def grid_node_levels(node_type: str, p: dict, d: int):
    """The levels (inshade/grid_layout.py) of a resolved hash_grid / dense_grid node."""
    try:
        return grid_levels(d, p["levels"], p["base_resolution"], p["per_level_scale"],
                           p.get("log2_table_size", 24), GRID_KINDS[node_type])
    except GridLayoutError as exc:
        raise ComponentError(str(exc)) from None


def _grid_tensors(node_type):
    return lambda p, d: {"table": TensorSpec((table_rows(grid_node_levels(node_type, p, d)), p["features"]),
                                             "float32", GRID_PRECISIONS[p["precision"]])}


def _grid_checks(node_type):
    return lambda p, d: _check_grid(node_type, p, d)


def _check_grid(node_type, p, d):
    levels = grid_node_levels(node_type, p, d)
    if GRID_KINDS[node_type] == "dense" and levels[-1].resolution > MAX_DENSE_RESOLUTION[d]:
        raise ComponentError(f"levels: the finest dense level has {levels[-1].resolution} vertices per axis, "
                             f"more than {MAX_DENSE_RESOLUTION[d]} (its index would overflow uint32)")
    if table_rows(levels) > MAX_GRID_ROWS:
        raise ComponentError(f"levels: the table needs {table_rows(levels)} rows, more than {MAX_GRID_ROWS}")


_GRID_PARAMS = {
    "levels": Param(int, check=_pos_int(32), doc="1..32"),
    "features": Param(int, 2, lambda v: v in (1, 2, 4, 8), doc="1, 2, 4 or 8 per level"),
    "base_resolution": Param(int, 16, _pos_int(1 << 16), doc="vertices per axis of level 0"),
    "per_level_scale": Param(float, 2.0, lambda v: np.isfinite(v) and 1.0 <= v <= 16.0, doc="1..16"),
    "precision": Param(str, "f16", lambda v: v in GRID_PRECISIONS),
}
_register(ComponentSpec(
    "hash_grid",
    "multiresolution hash encoding (instant-NGP, tiny-cuda-nn's Grid/HashGrid): input x in [0, 1]^dims "
    "(dims 2 or 3); per level a grid of resolution ceil(scale)+1, dense indexing where it fits the "
    "level's rows, else the spatial hash; linear interpolation; output levels*features lanes",
    {**_GRID_PARAMS,
     "log2_table_size": Param(int, 19, _pos_int(24), doc="1..24"),
     "hash": Param(str, "coherent_prime", lambda v: v in ("coherent_prime", "prime", "reversed_prime"))},
    out_dim=lambda p, d: p["levels"] * p["features"],
    tensors=_grid_tensors("hash_grid"),
    in_dim=lambda p, d: d in (2, 3),
    category="lookup",
    extra_checks=_grid_checks("hash_grid"),
))
_register(ComponentSpec(
    "dense_grid",
    "multiresolution dense grid (tiny-cuda-nn's DenseGrid): the hash grid's rules with every level "
    "indexed densely (rows = resolution^dims rounded up to 8)",
    dict(_GRID_PARAMS),
    out_dim=lambda p, d: p["levels"] * p["features"],
    tensors=_grid_tensors("dense_grid"),
    in_dim=lambda p, d: d in (2, 3),
    category="lookup",
    extra_checks=_grid_checks("dense_grid"),
))


# --- residual connection ------------------------------------------------------------------------

_register(ComponentSpec(
    "add", "residual connection: input [a (n lanes), b (n lanes)] -> a + b (n lanes)",
    {},
    out_dim=lambda p, d: d // 2,
    in_dim=lambda p, d: d >= 2 and d % 2 == 0,
    category="layer",
))


# --- deep appearance prefiltering (Bako et al. 2022): sparse multi-scale voxel latents ----------

VOXEL_PRECISIONS = {"f16": "float16", "f32": None}
VOXEL_MAX_SCALE = 9                 # 512^3 cells: the finest grid a 3D index texture may hold
VOXEL_MAX_COUNT = 1 << 24           # slots travel through torch as exact float32 integers
VOXEL_INDEXES = ("dense", "bricks")  # cell -> slot index layouts (codegen/voxel_index.py)
VOXEL_BRICKS = (2, 4, 8)


def _voxel_checks(p, d):
    if not 0 <= p["scale_min"] <= p["scale_max"]:
        raise ComponentError(f"scale_min: must be <= scale_max ({p['scale_max']}), got {p['scale_min']}")


def check_voxel_tables(cells: np.ndarray, spheres: np.ndarray, scale_min: int, scale_max: int,
                       latents: np.ndarray | None = None) -> None:
    """The voxel tables of a sparse_voxels node (models/sparse_voxels.py has the rules): cells
    [N, 4] (scale, i, j, k) in range and sorted by (scale, k, j, i) without repeats, spheres
    [N, 4] finite with radius >= 1e-6, latents [N, Z] finite. One ComponentError naming the field.
    The index grid built from these tables holds slot + 1 for slot < N by construction, so it
    cannot point past the latent table: N equal across the three tables is what is checked."""
    cells, spheres = np.asarray(cells), np.asarray(spheres)
    if cells.ndim != 2 or cells.shape[1] != 4 or cells.dtype.kind not in "iu":
        raise ComponentError(f"cells: must be integer [N, 4] (scale, i, j, k), got {cells.dtype} {list(cells.shape)}")
    n = cells.shape[0]
    if spheres.shape != (n, 4):
        raise ComponentError(f"spheres: shape {list(spheres.shape)}, expected {[n, 4]} (one per cell)")
    if latents is not None and (np.ndim(latents) != 2 or np.shape(latents)[0] != n):
        raise ComponentError(f"latents: shape {list(np.shape(latents))}, expected [{n}, Z] (one row per cell: "
                             f"the index grid points at rows 0..{n - 1})")
    c = cells.astype(np.int64)
    scale = c[:, 0]
    bad = np.flatnonzero((scale < scale_min) | (scale > scale_max))
    if bad.size:
        raise ComponentError(f"cells: row {bad[0]} has scale {scale[bad[0]]}, outside scale_min..scale_max "
                             f"{scale_min}..{scale_max}")
    bad = np.flatnonzero(((c[:, 1:] < 0) | (c[:, 1:] >= (1 << scale)[:, None])).any(1))
    if bad.size:
        r = bad[0]
        raise ComponentError(f"cells: row {r} (scale {scale[r]}, cell {c[r, 1:].tolist()}) is outside the "
                             f"{1 << scale[r]}^3 grid of its scale")
    if n > 1:
        key = ((scale << 30 | c[:, 3] << 20) | c[:, 2] << 10) | c[:, 1]    # (scale, k, j, i), each < 2^10
        step = np.diff(key)
        bad = np.flatnonzero(step <= 0)
        if bad.size:
            r = bad[0] + 1
            what = "repeats" if step[bad[0]] == 0 else "is out of order"
            raise ComponentError(f"cells: row {r} {c[r].tolist()} {what} (rows must be sorted by (scale, k, j, i), "
                                 f"without repeats)")
    if not np.isfinite(spheres).all():
        raise ComponentError(f"spheres: NaN or Inf at row {int(np.argwhere(~np.isfinite(spheres))[0, 0])}")
    bad = np.flatnonzero(spheres[:, 3] < 1e-6)
    if bad.size:
        raise ComponentError(f"spheres: row {bad[0]} has radius {float(spheres[bad[0], 3]):.9g} (must be >= 1e-6)")
    if latents is not None:
        lat = np.asarray(latents)
        finite = np.isfinite(lat)
        if not finite.all():
            r = int(np.argwhere(~finite)[0, 0])
            raise ComponentError(f"latents: {'NaN' if np.isnan(lat[r]).any() else 'Inf'} at row {r}")


_register(ComponentSpec(
    "sparse_voxels",
    "sparse multi-scale voxel latents: input the slot (a voxel's row, uint or an exact float); "
    "output latents[slot] (channels lanes). cells [N, 4] (scale, i, j, k) sorted by (scale, k, j, i), "
    "spheres [N, 4] (centre, radius) of the geometry in each voxel; the GLSL side also emits the "
    "index grid (P_voxel_slot) and the spheres (P_voxel_sphere)",
    {"voxels": Param(int, check=_pos_int(VOXEL_MAX_COUNT), doc=f"1..{VOXEL_MAX_COUNT}"),
     "channels": Param(int, check=lambda v: isinstance(v, int) and 4 <= v <= 64 and v % 4 == 0,
                       doc="a multiple of 4 from 4 to 64: Z/4 RGBA texels per voxel"),
     "scale_min": Param(int, check=lambda v: 0 <= v <= VOXEL_MAX_SCALE, doc=f"0..{VOXEL_MAX_SCALE}"),
     "scale_max": Param(int, check=lambda v: 0 <= v <= VOXEL_MAX_SCALE, doc=f"0..{VOXEL_MAX_SCALE}"),
     "precision": Param(str, "f16", lambda v: v in VOXEL_PRECISIONS),
     "index": Param(str, "dense", lambda v: v in VOXEL_INDEXES,
                    doc="dense (one 3D grid per scale) or bricks (a brick table + B^3 bricks where voxels are)"),
     "brick": Param(int, 4, lambda v: v in VOXEL_BRICKS, doc="the bricks index's side B: 2, 4 or 8")},
    out_dim=lambda p, d: p["channels"],
    tensors=lambda p, d: {
        "latents": TensorSpec((p["voxels"], p["channels"]), "float32", VOXEL_PRECISIONS[p["precision"]]),
        "cells": TensorSpec((p["voxels"], 4), "uint32"),
        "spheres": TensorSpec((p["voxels"], 4), "float32")},
    in_dim=lambda p, d: d == 1,
    category="lookup",
    extra_checks=_voxel_checks,
))

def resolve_params(node_type: str, params: dict) -> dict:
    """Validated params with defaults filled in; raises ComponentError naming the field."""
    if node_type not in COMPONENTS:
        raise ComponentError(f"unknown component type: {node_type}")
    spec = COMPONENTS[node_type]
    if not isinstance(params, dict):
        raise ComponentError("params must be an object")
    extra = sorted(set(params) - set(spec.params))
    if extra:
        raise ComponentError(f"unknown params for {node_type}: {', '.join(extra)}")
    out = {}
    for name, p in spec.params.items():
        if name not in params or params[name] is None and p.default is None:
            if p.default is ...:
                raise ComponentError(f"missing param '{name}' for {node_type}")
            out[name] = p.default
            continue
        v = params[name]
        if p.kind is float and isinstance(v, int) and not isinstance(v, bool):
            v = float(v)
        if p.kind is int and isinstance(v, bool) or not isinstance(v, p.kind):
            raise ComponentError(f"param '{name}' of {node_type} must be {p.kind.__name__}, got {v!r}")
        if p.check is not None and not p.check(v):
            why = f" (must be {p.doc})" if p.doc else ""
            raise ComponentError(f"param '{name}' of {node_type} has an invalid value {v!r}{why}")
        out[name] = v
    return out


def check_node(node_type: str, params: dict, in_dim: int) -> int:
    """Checks a resolved node against its input width and returns its output width."""
    spec = COMPONENTS[node_type]
    if spec.in_dim is not None and not spec.in_dim(params, in_dim):
        raise ComponentError(f"{node_type} cannot take a {in_dim}-wide input")
    if spec.extra_checks is not None:
        spec.extra_checks(params, in_dim)
    return spec.out_dim(params, in_dim)
