"""tiny-cuda-nn's forward pass in plain torch, written from its source (NVlabs/tiny-cuda-nn at
6ee3546b) for the converter's tests: it takes the JSON config and the flat parameter vector
exactly as the torch bindings hold them and shares no code with inshade's lowering or components,
so a test comparing the two checks the layout rules instead of restating them.

What each piece follows (file: function):

- model forms: bindings/torch/tinycudann/modules.py, src/cpp_api.cu (create_network is an
  Identity encoding + the network), network_with_input_encoding.h (encoding padded to the
  network's alignment; parameters: network, then encoding);
- padding: encoding.h set_alignment, composite.h (constructor, set_padded_output_width);
  which value pad lanes hold and where: each encoding's kernel;
- Grid: grid.h GridEncodingTemplated (offset table), kernel_grid (forward), common_device.h
  grid_scale, grid_resolution, grid_index, the lcg hashes, pos_fract;
- Frequency, Identity, OneBlob (kernel_one_blob_soa), SphericalHarmonics (sh_enc),
  TriangleWave, Composite: their headers under encodings/;
- networks: fully_fused_mlp.cu / cutlass_mlp.cu constructors (matrix shapes, row-major
  [out][in]), network.cu create_network (defaults), common_device.h warp_activation.

Numerics: float32 values; where tiny-cuda-nn fuses a multiply-add (pos_fract's fmaf, the grid's
fma accumulation, Identity's and Frequency's x * a + b, which the JIT path writes as fma and nvcc
contracts) the value is computed in float64 and rounded once to float32. Host-side constants
(grid_scale for the offset table, the Dense default per_level_scale) use the C library's
log2f / exp2f / logf / expf as tiny-cuda-nn's host code does (libm through ctypes; float64
rounded once where there is none). Not reproduced: fp16 storage of activations and fp16
accumulation (tiny-cuda-nn's default precision), --use_fast_math's approximate __sinf / __expf,
the device's own exp2f for the level scale.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import math

import numpy as np
import torch

PI_F32 = np.float32(3.14159265358979323846)            # common.h PI()
MAX_BASES = {1: 0xFFFFFFFF, 2: 0xFFFF, 3: 0x659, 4: 0xFF}   # common_device.h grid_index
PRIMES = {   # common_device.h prime_hash, coherent_prime_hash, reversed_prime_hash
    "prime": (1958374283, 2654435761, 805459861, 3674653429),
    "coherentprime": (1, 2654435761, 805459861, 3674653429),
    "reversedprime": (2165219737, 1434869437, 2097192037, 3674653429),
}
U32 = 0xFFFFFFFF


def _libm():
    name = ctypes.util.find_library("m")
    if name is None:
        return None
    lib = ctypes.CDLL(name)
    for fn in ("log2f", "exp2f", "logf", "expf"):
        getattr(lib, fn).restype = ctypes.c_float
        getattr(lib, fn).argtypes = [ctypes.c_float]
    return lib


LIBM = _libm()


def _host(fn: str, x) -> np.float32:
    """A C float function on the host (glibc's, as tiny-cuda-nn's host code calls it)."""
    x = float(np.float32(x))
    if LIBM is not None:
        return np.float32(getattr(LIBM, fn)(x))
    return np.float32({"log2f": math.log2, "exp2f": lambda v: 2.0 ** v, "logf": math.log, "expf": math.exp}[fn](x))


def f32(t: torch.Tensor) -> torch.Tensor:
    return t.to(torch.float32)


def fused(a: torch.Tensor, b, c) -> torch.Tensor:
    """fmaf(a, b, c): float32 operands, exact product and sum in float64, one rounding."""
    a64 = a.to(torch.float64)
    b64 = b.to(torch.float64) if isinstance(b, torch.Tensor) else torch.tensor(float(np.float32(b)), dtype=torch.float64)
    c64 = c.to(torch.float64) if isinstance(c, torch.Tensor) else torch.tensor(float(np.float32(c)), dtype=torch.float64)
    return f32(a64 * b64 + c64)


def _lower(v) -> str:
    return v.lower() if isinstance(v, str) else v


def next_multiple(n, m):
    return (n + m - 1) // m * m


# === the model as tiny-cuda-nn builds it ======================================================

def grid_scale(level: int, per_level_scale, base_resolution: int) -> np.float32:
    """grid_scale(level, std::log2(per_level_scale), base): exp2f(level * log2) * base - 1.0f."""
    log2_scale = _host("log2f", per_level_scale)
    with np.errstate(invalid="ignore"):
        e = _host("exp2f", np.float32(np.float32(level) * log2_scale))
    return np.float32(np.float32(e * np.float32(base_resolution)) - np.float32(1.0))


def grid_offsets(dims, n_levels, base, per_level_scale, log2_hashmap_size, grid_type):
    """GridEncodingTemplated's constructor: per level (scale, resolution, params_in_level, offset)."""
    out, offset = [], 0
    for i in range(n_levels):
        scale = grid_scale(i, per_level_scale, base)
        resolution = int(math.ceil(float(scale))) + 1          # grid_resolution: (uint32_t)ceilf(scale) + 1
        max_params = U32 // 2
        params = max_params if float(resolution) ** dims > float(np.float32(max_params)) else resolution ** dims
        params = next_multiple(params, 8)
        if grid_type == "hash":
            params = min(params, 1 << log2_hashmap_size)
        out.append((scale, resolution, params, offset))
        offset += params
    return out


def _encoding(cfg: dict, n: int, alignment: int) -> dict:
    """create_encoding(n_dims_to_encode, encoding, alignment) as a dict: out (lanes computed),
    pad, pad_value, pad_first, align (required_output_alignment), n_params and the settings."""
    otype = _lower(cfg.get("otype", "OneBlob"))
    if otype in ("nrc", "oneblobfrequency"):   # encoding.cu nrc_factory
        return _encoding({"otype": "Composite", "nested": [
            {"n_dims_to_encode": 3, "otype": "TriangleWave", "n_frequencies": cfg.get("n_frequencies", 12)},
            {"n_dims_to_encode": 5, "otype": "OneBlob", "n_bins": cfg.get("n_bins", 4)},
            {"otype": "Identity"}]}, n, alignment)
    e = {"otype": otype, "n": n, "pad": 0, "pad_value": 1.0, "pad_first": False, "align": 1, "n_params": 0}
    if otype == "identity":
        e.update(out=n, scale=float(np.float32(cfg.get("scale", 1.0))), offset=float(np.float32(cfg.get("offset", 0.0))))
    elif otype == "frequency":
        e.update(F=cfg.get("n_frequencies", 12))
        e["out"] = n * e["F"] * 2
    elif otype == "trianglewave":
        e.update(F=cfg.get("n_frequencies", 12))
        e["out"] = n * e["F"]
    elif otype == "oneblob":
        e.update(bins=cfg.get("n_bins", 16))
        e["out"] = n * e["bins"]
    elif otype == "sphericalharmonics":
        e.update(degree=cfg.get("degree", 4), pad_first=True)
        e["out"] = e["degree"] ** 2
    elif otype == "empty":
        e["out"] = 0
    elif otype in ("grid", "hashgrid", "densegrid"):
        F = cfg.get("n_features_per_level", 2)
        levels = cfg["n_features"] // F if "n_features" in cfg else cfg.get("n_levels", 16)
        gtype = _lower(cfg.get("type", "dense" if otype == "densegrid" else "hash"))
        base = cfg.get("base_resolution", 16)
        if "per_level_scale" in cfg:
            pls = np.float32(cfg["per_level_scale"])
        elif gtype == "dense":   # std::exp(std::log(256.0f / (float)base) / (n_levels - 1))
            with np.errstate(divide="ignore", invalid="ignore"):   # n_levels 1: tiny-cuda-nn divides by 0 too
                pls = _host("expf", np.float32(_host("logf", np.float32(256.0) / np.float32(base))
                                               / np.float32(levels - 1)))
        else:
            pls = np.float32(2.0)
        log2 = cfg.get("log2_hashmap_size", 19)
        table = grid_offsets(n, levels, base, pls, log2, gtype)
        e.update(F=F, levels=levels, gtype=gtype, table=table, hash=_lower(cfg.get("hash", "CoherentPrime")),
                 per_level_scale=float(pls), base_resolution=base,
                 out=levels * F, align=F, pad_value=0.0)
        e["n_params"] = (table[-1][3] + table[-1][2]) * F
    elif otype == "composite":
        nested, offset, begins = [], 0, []
        known = sum(c.get("n_dims_to_encode", 0) for c in cfg["nested"])
        explicit = any("dims_to_encode_begin" in c for c in cfg["nested"])
        rest = None if explicit else n - known
        for c in cfg["nested"]:
            if "n_dims_to_encode" in c:
                offset = c.get("dims_to_encode_begin", offset)
                count = c["n_dims_to_encode"]
            else:
                count, rest = rest, None
            if count > 0:
                nested.append(_encoding(c, count, 1))
                begins.append(offset)
            offset += count
        so_far = 0
        for i in range(len(nested) - 1):   # pad each to the next one's alignment
            want = next_multiple(so_far + _width(nested[i]), nested[i + 1]["align"]) - so_far
            _set_padded(nested[i], want)
            so_far += _width(nested[i])
        e.update(nested=nested, begins=begins, align=math.lcm(*(x["align"] for x in nested)),
                 n_params=sum(x["n_params"] for x in nested))
        e["out"] = None
    else:
        raise ValueError(f"reference: encoding {otype!r} not written")
    if alignment > 0:
        _set_alignment(e, alignment)
    return e


def _width(e: dict) -> int:
    """padded_output_width()."""
    if e["otype"] == "composite":
        return sum(_width(x) for x in e["nested"])
    return e["out"] + e["pad"]


def _set_padded(e: dict, width: int) -> None:
    if e["otype"] == "composite":
        last = e["nested"][-1]
        _set_padded(last, width - (_width(e) - _width(last)))
    else:
        e["pad"] = width - e["out"]


def _set_alignment(e: dict, alignment: int) -> None:
    _set_padded(e, next_multiple(_width(e), math.lcm(alignment, e["align"])))


def build(config: dict, n_input_dims=None, n_output_dims=None) -> dict:
    """The model: kind, n_in, n_out, encoding (dict), network (dict or None), n_params."""
    n_in = config.get("n_input_dims", n_input_dims)
    n_out = config.get("n_output_dims", n_output_dims)
    if "network" in config:
        enc = _encoding(config.get("encoding", {"otype": "Identity"}), n_in, 8)
        _set_alignment(enc, 16)
        cfg = config["network"]
        otype = _lower(cfg.get("otype", "MLP"))
        width, hidden = cfg.get("n_neurons", 128), cfg.get("n_hidden_layers", 5)
        padded_out = next_multiple(n_out, 16)
        n_enc = _width(enc)
        if hidden == 0:
            shapes = [(padded_out, n_enc)]
        else:
            shapes = [(width, n_enc)] + [(width, width)] * (hidden - 1) + [(padded_out, width)]
        net = {"otype": otype, "shapes": shapes, "activation": _lower(cfg.get("activation", "ReLU")),
               "output_activation": _lower(cfg.get("output_activation", "None"))}
        n_params = sum(a * b for a, b in shapes) + enc["n_params"]
        return {"kind": "NetworkWithInputEncoding", "n_in": n_in, "n_out": n_out, "encoding": enc, "network": net,
                "n_params": n_params}
    enc = _encoding(config["encoding"], n_in, 0)
    return {"kind": "Encoding", "n_in": n_in, "n_out": _width(enc), "encoding": enc, "network": None,
            "n_params": enc["n_params"]}


# === the forward pass =========================================================================

def grid_index(coords: np.ndarray, resolution: int, hashmap_size: int, grid_type: str, hash_name: str) -> np.ndarray:
    """common_device.h grid_index, on uint32 coordinates [..., dims]: dense index where the level
    fits (resolution within MAX_BASES and resolution^dims <= hashmap_size, or a Dense grid), else
    the lcg hash; then % hashmap_size."""
    c = np.asarray(coords, np.uint64) & U32
    dims = c.shape[-1]
    index = np.zeros(c.shape[:-1], np.uint64)
    stride = 1
    if resolution <= MAX_BASES[dims]:
        for d in range(dims):
            index = (index + c[..., d] * np.uint64(stride)) & U32
            stride = (stride * resolution) & U32
    else:
        stride = U32
    if grid_type == "hash" and hashmap_size < stride:
        index = np.zeros(c.shape[:-1], np.uint64)
        for d in range(dims):
            index ^= (c[..., d] * np.uint64(PRIMES[hash_name][d])) & U32
    return (index % np.uint64(hashmap_size)).astype(np.int64)


def _grid(e: dict, x: torch.Tensor, table: np.ndarray, position: str) -> torch.Tensor:
    """kernel_grid, Linear interpolation: per level pos = fmaf(scale, x, 0.5), corner weights
    multiplied dim by dim, result = fma(weight, value, result) corner by corner."""
    F, dims = e["F"], e["n"]
    outs = []
    for scale, resolution, rows, offset in e["table"]:
        s = torch.tensor(float(scale), dtype=torch.float32)
        pos = fused(x, s, 0.5) if position == "fma" else f32(x * s) + 0.5   # unfused: what GLSL 3.30 writes
        floor = torch.floor(pos)
        frac = pos - floor
        grid = floor.to(torch.int64).numpy().astype(np.int64) & U32       # (uint32_t)(int)floor
        level_table = torch.from_numpy(table[offset * F:(offset + rows) * F].reshape(rows, F).astype(np.float32))
        result = torch.zeros(x.shape[0], F, dtype=torch.float32)
        for corner in range(1 << dims):
            weight = torch.ones(x.shape[0], dtype=torch.float32)
            local = grid.copy()
            for d in range(dims):
                if corner & (1 << d):
                    weight = weight * frac[:, d]
                    local[:, d] += 1
                else:
                    weight = weight * (1 - frac[:, d])
            index = grid_index(local, resolution, rows, e["gtype"], e["hash"])
            result = fused(weight[:, None], level_table[torch.from_numpy(index)], result)
        outs.append(result)
    return torch.cat(outs, 1)


def _frequency(e: dict, x: torch.Tensor) -> torch.Tensor:
    """frequency_encoding: lane j of input j / (2F), log2 frequency (j / 2) % F, phase (j % 2) pi/2;
    sin(scalbnf(x, f) * PI() + phase). sin evaluated accurately (tiny-cuda-nn: __sinf)."""
    cols = []
    for i in range(e["n"]):
        for f in range(e["F"]):
            for s in (0, 1):
                scaled = x[:, i] * (2.0 ** f)                       # scalbnf: exact
                arg = fused(scaled, PI_F32, np.float32(s * (PI_F32 / np.float32(2))))
                cols.append(f32(torch.sin(arg.to(torch.float64))))
    return torch.stack(cols, 1)


def _triangle_wave(e: dict, x: torch.Tensor) -> torch.Tensor:
    cols = []
    for i in range(e["n"]):
        for f in range(e["F"]):
            val = x[:, i] * (2.0 ** (f - 1)) + np.float32(f * 0.25)
            cols.append(torch.abs(val - torch.floor(val) - 0.5) * 4 - 1)
    return torch.stack(cols, 1)


def _quartic_cdf(t: torch.Tensor, inv_radius: float) -> torch.Tensor:
    u = t * inv_radius
    u2 = u * u
    u4 = u2 * u2
    two_thirds, one_fifth, k = np.float32(2.0 / 3.0), np.float32(1.0 / 5.0), np.float32(15.0 / 16.0)
    return torch.clamp(k * u * (1 - two_thirds * u2 + one_fifth * u4) + 0.5, 0.0, 1.0)


def _one_blob(e: dict, x: torch.Tensor) -> torch.Tensor:
    """kernel_one_blob_soa: the wrapped quartic blob's mass in each of the n_bins bins."""
    B = e["bins"]
    cols = []
    for i in range(e["n"]):
        v = x[:, i]
        k3 = lambda b: _quartic_cdf(b - v, B) + _quartic_cdf(b - v - 1.0, B) + _quartic_cdf(b - v + 1.0, B)
        left = _quartic_cdf(-v, B) + _quartic_cdf(-v - 1.0, B) + _quartic_cdf(-v + 1.0, B)
        for k in range(B):
            right = k3(torch.tensor((k + 1) / B, dtype=torch.float32))
            cols.append(right - left)
            left = right
    return torch.stack(cols, 1)


def _sh(e: dict, v: torch.Tensor) -> torch.Tensor:
    """sh_enc on (2x - 1, 2y - 1, 2z - 1), degrees up to 5 (25 lanes)."""
    x, y, z = (v[:, i] * 2.0 - 1.0 for i in range(3))
    xy, xz, yz, x2, y2, z2 = x * y, x * z, y * z, x * x, y * y, z * z
    x4, y4, z4 = x2 * x2, y2 * y2, z2 * z2
    c = lambda a: np.float32(a)
    out = [torch.full_like(x, float(c(0.28209479177387814)))]
    if e["degree"] > 1:
        out += [c(-0.48860251190291987) * y, c(0.48860251190291987) * z, c(-0.48860251190291987) * x]
    if e["degree"] > 2:
        out += [c(1.0925484305920792) * xy, c(-1.0925484305920792) * yz,
                c(0.94617469575755997) * z2 - c(0.31539156525251999), c(-1.0925484305920792) * xz,
                c(0.54627421529603959) * x2 - c(0.54627421529603959) * y2]
    if e["degree"] > 3:
        out += [c(0.59004358992664352) * y * (-3.0 * x2 + y2), c(2.8906114426405538) * xy * z,
                c(0.45704579946446572) * y * (1.0 - 5.0 * z2), c(0.3731763325901154) * z * (5.0 * z2 - 3.0),
                c(0.45704579946446572) * x * (1.0 - 5.0 * z2), c(1.4453057213202769) * z * (x2 - y2),
                c(0.59004358992664352) * x * (-x2 + 3.0 * y2)]
    if e["degree"] > 4:
        out += [c(2.5033429417967046) * xy * (x2 - y2), c(1.7701307697799304) * yz * (-3.0 * x2 + y2),
                c(0.94617469575756008) * xy * (7.0 * z2 - 1.0), c(0.66904654355728921) * yz * (3.0 - 7.0 * z2),
                c(-3.1735664074561294) * z2 + c(3.7024941420321507) * z4 + c(0.31735664074561293),
                c(0.66904654355728921) * xz * (3.0 - 7.0 * z2),
                c(0.47308734787878004) * (x2 - y2) * (7.0 * z2 - 1.0),
                c(1.7701307697799304) * xz * (-x2 + 3.0 * y2),
                c(-3.7550144126950569) * x2 * y2 + c(0.62583573544917614) * x4 + c(0.62583573544917614) * y4]
    if e["degree"] > 5:
        raise ValueError("reference: SH degrees above 5 not written")
    return torch.stack(out, 1)


def encode(e: dict, x: torch.Tensor, params: np.ndarray, position: str = "fma") -> torch.Tensor:
    """The encoding's padded output [N, padded_output_width]; ``params`` its own parameters."""
    otype = e["otype"]
    if otype == "composite":
        parts, at = [], 0
        for nested, begin in zip(e["nested"], e["begins"]):
            parts.append(encode(nested, x[:, begin:begin + nested["n"]], params[at:at + nested["n_params"]],
                                position))
            at += nested["n_params"]
        return torch.cat(parts, 1)
    if otype == "identity":
        core = fused(x, e["scale"], e["offset"])
    elif otype == "frequency":
        core = _frequency(e, x)
    elif otype == "trianglewave":
        core = _triangle_wave(e, x)
    elif otype == "oneblob":
        core = _one_blob(e, x)
    elif otype == "sphericalharmonics":
        core = _sh(e, x)
    elif otype == "empty":
        core = torch.zeros(x.shape[0], 0)
    else:
        core = _grid(e, x, params, position)
    pad = torch.full((x.shape[0], e["pad"]), e["pad_value"], dtype=torch.float32)
    return torch.cat([pad, core] if e["pad_first"] else [core, pad], 1)


def activation(name: str, v: torch.Tensor, dtype: str = "float32") -> torch.Tensor:
    """common_device.h warp_activation with T the network's precision (only LeakyReLU's constant
    depends on it: (T)0.01f)."""
    k_act = 10.0
    if name == "none":
        return v
    if name == "relu":
        return torch.clamp_min(v, 0.0)
    if name == "leakyrelu":
        slope = float(np.float16(0.01)) if dtype == "float16" else float(np.float32(0.01))
        return v * torch.where(v > 0, 1.0, slope)
    if name == "silu":
        return v * (1.0 / (1.0 + torch.exp(-v)))
    if name == "exponential":
        return torch.exp(v)
    if name == "sine":
        return torch.sin(v)
    if name == "sigmoid":
        return 1.0 / (1.0 + torch.exp(-v))
    if name == "squareplus":
        xx = v * k_act
        return 0.5 * (xx + torch.sqrt(xx * xx + 4)) / k_act
    if name == "softplus":
        return torch.log(torch.exp(v * k_act) + 1.0) / k_act
    if name == "tanh":
        return torch.tanh(v)
    raise ValueError(f"reference: activation {name!r} not written")


def matrices(model: dict, params: np.ndarray) -> list[np.ndarray]:
    """The network's weight matrices [rows, cols] (row-major, in parameter order)."""
    out, at = [], 0
    for rows, cols in model["network"]["shapes"]:
        out.append(np.asarray(params[at:at + rows * cols], np.float32).reshape(rows, cols))
        at += rows * cols
    return out


def forward(config: dict, params, x, *, n_input_dims=None, n_output_dims=None, dtype: str = "float32",
            position: str = "fma", trace: list | None = None) -> np.ndarray:
    """The model's output [N, n_output_dims] (float32) for inputs x [N, n_input_dims].
    ``position``: "fma" (tiny-cuda-nn) or "unfused" (scale * x + 0.5 rounded twice, as GLSL).
    ``trace``: when a list, gets the network's input and each layer's pre-activation."""
    model = build(config, n_input_dims, n_output_dims)
    params = np.asarray(params, np.float32)
    x = torch.as_tensor(np.asarray(x, np.float32))
    with torch.no_grad():
        if model["network"] is None:
            return encode(model["encoding"], x, params, position).numpy()
        net = model["network"]
        mats = matrices(model, params)
        h = encode(model["encoding"], x, params[sum(m.size for m in mats):], position)
        if trace is not None:
            trace.append(h.numpy())
        for i, w in enumerate(mats):
            pre = h @ torch.from_numpy(w).T
            if trace is not None:
                trace.append(pre.numpy())
            h = activation(net["output_activation"] if i == len(mats) - 1 else net["activation"], pre, dtype)
        return h[:, :model["n_out"]].numpy()
