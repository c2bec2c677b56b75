"""A tiny-cuda-nn model as tiny-cuda-nn builds it from its JSON config: every encoding with the
defaults its factory fills in, its output width, its padding (how many lanes, holding which value,
where) and its parameter count; the network's weight matrices in the order they lie in the flat
parameter vector. Numbers only (no torch): inshade/convert/tcnn.py lowers the description onto
bundle components; docs/tcnn.md cites the tiny-cuda-nn source of every rule.

The three model forms are the torch bindings' (bindings/torch/tinycudann/modules.py):

- ``NetworkWithInputEncoding`` ({"encoding", "network"}): the encoding's output padded to the
  network's alignment (16), then the MLP; parameters: the network's, then the encoding's
  (network_with_input_encoding.h, set_params_impl).
- ``Network`` ({"network"} only): src/cpp_api.cu create_network is a NetworkWithInputEncoding
  whose encoding is Identity, so the raw inputs are padded with ones to 16 lanes.
- ``Encoding`` ({"encoding"} only): create_encoding with alignment 0 (no padding at the top; a
  Composite still pads its nested encodings to each other's alignment).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from inshade.grid_layout import MAX_LEVELS, GridLayoutError, grid_levels, table_rows

from .lowering import ConvertError

NETWORK_ALIGNMENT = 16          # FullyFusedMLP / CutlassMLP REQUIRED_ALIGNMENT()
OUTPUT_ALIGNMENT = 16           # the output layer's rows are padded to a multiple of this
ENCODING_ALIGNMENT = 8          # create_encoding's default alignment (encoding.h)
FULLY_FUSED_WIDTHS = (16, 32, 64, 128)
# the hidden activations the half-precision FullyFusedMLP kernels are instantiated for
# (src/fully_fused_mlp.cu inference_mixed_precision_impl: any other throws "Unsupported activation.")
FULLY_FUSED_HIDDEN = ("none", "exponential", "sigmoid", "relu", "leakyrelu", "squareplus", "softplus", "tanh")
ACTIVATIONS = ("none", "relu", "leakyrelu", "silu", "exponential", "sine", "sigmoid", "squareplus", "softplus",
               "tanh")
GRID_HASHES = {"coherentprime": "coherent_prime", "prime": "prime", "reversedprime": "reversed_prime"}
MODEL_KEYS = ("encoding", "network", "n_input_dims", "n_output_dims", "otype")
SKIPPED_TOP_KEYS = ("loss", "optimizer")   # tiny-cuda-nn's sample configs carry the training setup too


def next_multiple(n: int, m: int) -> int:
    return -(-n // m) * m


@dataclass
class Context:
    """Where the config came from (for messages) and what it held that tiny-cuda-nn ignores."""
    source: str
    ignored: list = field(default_factory=list)

    def error(self, where: str, message: str) -> ConvertError:
        return ConvertError(f"{self.source}: {where}: {message}")


# --- reading JSON values the way tiny-cuda-nn's json.value(key, default) does ------------------

class Reader:
    """One JSON object of the config; ``take`` marks keys as read, ``done`` records the rest."""

    def __init__(self, ctx: Context, obj, where: str):
        if not isinstance(obj, dict):
            raise ctx.error(where, f"expected a JSON object, got {type(obj).__name__}")
        self.ctx, self.obj, self.where, self.read = ctx, obj, where, {"otype"}

    def _path(self, key: str) -> str:
        return f"{self.where}.{key}" if self.where else key

    def has(self, key: str) -> bool:
        return key in self.obj

    def uint(self, key: str, default: int | None) -> int:
        self.read.add(key)
        v = self.obj.get(key, default)
        if v is None:
            raise self.ctx.error(self._path(key), "missing (no default in tiny-cuda-nn)")
        if isinstance(v, bool) or not isinstance(v, int) or v < 0:
            raise self.ctx.error(self._path(key), f"expected a non-negative integer, got {v!r}")
        return int(v)

    def number(self, key: str, default) -> float:
        self.read.add(key)
        v = self.obj.get(key, default)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise self.ctx.error(self._path(key), f"expected a number, got {v!r}")
        return float(np.float32(v))   # tiny-cuda-nn reads these fields as float

    def boolean(self, key: str, default: bool) -> bool:
        self.read.add(key)
        v = self.obj.get(key, default)
        if not isinstance(v, bool):
            raise self.ctx.error(self._path(key), f"expected true or false, got {v!r}")
        return v

    def word(self, key: str, default: str, choices) -> str:
        """A case-insensitive name (tiny-cuda-nn's equals_case_insensitive), lower-cased."""
        self.read.add(key)
        v = self.obj.get(key, default)
        if not isinstance(v, str) or v.lower() not in choices:
            raise self.ctx.error(self._path(key), f"{v!r} is not one of {', '.join(choices)}")
        return v.lower()

    def done(self) -> None:
        self.ctx.ignored += [self._path(k) for k in self.obj if k not in self.read]


# --- encodings -------------------------------------------------------------------------------

class Encoding:
    """tiny-cuda-nn's Encoding<T>: ``out`` lanes computed, then ``pad`` lanes of ``pad_value``
    (before the computed ones where ``pad_first``)."""

    otype = ""
    alignment = 1          # required_output_alignment()
    pad_value = 1.0
    pad_first = False

    def __init__(self, where: str, n_dims: int):
        self.where, self.n_dims, self.out, self.pad = where, n_dims, 0, 0

    @property
    def padded(self) -> int:
        return self.out + self.pad

    def n_params(self) -> int:
        return 0

    def set_padded(self, width: int) -> None:   # set_padded_output_width
        if width < self.out:
            raise ValueError(f"{self.where}: padded width {width} < {self.out}")
        self.pad = width - self.out

    def set_alignment(self, alignment: int) -> None:   # Encoding<T>::set_alignment
        self.set_padded(next_multiple(self.padded, math.lcm(alignment, self.alignment)))

    def params_text(self) -> str:
        return ""

    def resolved(self) -> dict:
        return {"otype": self.otype}


class Identity(Encoding):
    otype = "Identity"

    def __init__(self, where, n_dims, r: Reader):
        super().__init__(where, n_dims)
        self.scale, self.offset = r.number("scale", 1.0), r.number("offset", 0.0)
        self.out = n_dims

    def resolved(self):
        return {"otype": self.otype, "scale": self.scale, "offset": self.offset}


class Frequency(Encoding):
    otype = "Frequency"

    def __init__(self, where, n_dims, r: Reader):
        super().__init__(where, n_dims)
        self.n_frequencies = r.uint("n_frequencies", 12)
        self.out = n_dims * self.n_frequencies * 2

    def resolved(self):
        return {"otype": self.otype, "n_frequencies": self.n_frequencies}


class SphericalHarmonics(Encoding):
    otype = "SphericalHarmonics"
    pad_first = True   # kernel_sh writes the padding lanes first

    def __init__(self, where, n_dims, r: Reader):
        super().__init__(where, n_dims)
        self.degree = r.uint("degree", 4)
        if n_dims != 3:
            raise r.ctx.error(where, f"SphericalHarmonics encodes 3 input lanes (a direction), got {n_dims}")
        if not 1 <= self.degree <= 8:
            raise r.ctx.error(f"{where}.degree", f"{self.degree}: tiny-cuda-nn takes degrees 1..8")
        self.out = self.degree ** 2

    def resolved(self):
        return {"otype": self.otype, "degree": self.degree}


class OneBlob(Encoding):
    otype = "OneBlob"

    def __init__(self, where, n_dims, r: Reader):
        super().__init__(where, n_dims)
        self.n_bins = r.uint("n_bins", 16)
        if self.n_bins < 1 or self.n_bins & (self.n_bins - 1):
            raise r.ctx.error(f"{where}.n_bins", f"{self.n_bins}: tiny-cuda-nn needs a power of two")
        self.out = n_dims * self.n_bins

    def resolved(self):
        return {"otype": self.otype, "n_bins": self.n_bins}


class TriangleWave(Encoding):
    otype = "TriangleWave"

    def __init__(self, where, n_dims, r: Reader):
        super().__init__(where, n_dims)
        self.n_frequencies = r.uint("n_frequencies", 12)
        self.out = n_dims * self.n_frequencies

    def resolved(self):
        return {"otype": self.otype, "n_frequencies": self.n_frequencies}


class Empty(Encoding):
    otype = "Empty"

    def __init__(self, where, n_dims, r: Reader):
        super().__init__(where, n_dims)


class Grid(Encoding):
    """GridEncodingTemplated (encodings/grid.h): ``levels`` (inshade.grid_layout's GridLevel, the
    same rules) and the table of ``rows`` x ``features`` parameters. Padding lanes hold 0."""

    otype = "Grid"
    pad_value = 0.0

    def __init__(self, where, n_dims, r: Reader, default_type: str):
        super().__init__(where, n_dims)
        err = r.ctx.error
        self.features = r.uint("n_features_per_level", 2)
        if self.features not in (1, 2, 4, 8):
            raise err(f"{where}.n_features_per_level", f"{self.features}: must be 1, 2, 4 or 8")
        if r.has("n_features") or r.has("n_grid_features"):
            if r.has("n_levels"):
                raise err(f"{where}.n_levels", "may not be given with n_features (one determines the other)")
            key = "n_features" if r.has("n_features") else "n_grid_features"
            n_features = r.uint(key, None)
            if n_features % self.features:
                raise err(f"{where}.{key}", f"{n_features} is not a multiple of n_features_per_level "
                                            f"{self.features}")
            self.levels = n_features // self.features
        else:
            self.levels = r.uint("n_levels", 16)
        if not 1 <= self.levels <= MAX_LEVELS:
            raise err(f"{where}.n_levels", f"{self.levels}: inshade's grid components take 1..{MAX_LEVELS} levels")
        self.type = r.word("type", default_type, ("hash", "dense", "tiled", "tile"))
        if self.type in ("tiled", "tile"):
            raise err(f"{where}.type", "Tiled grids are not supported (inshade lowers Hash and Dense grids)")
        self.log2_hashmap_size = r.uint("log2_hashmap_size", 19)
        self.base_resolution = r.uint("base_resolution", 16)
        if r.has("per_level_scale"):
            self.per_level_scale = r.number("per_level_scale", None)
        elif self.type == "dense":
            self.per_level_scale = dense_default_scale(self.base_resolution, self.levels)
            if not np.isfinite(self.per_level_scale):
                raise err(f"{where}.per_level_scale", f"missing, and tiny-cuda-nn's Dense default "
                          f"exp(log(256 / base_resolution) / (n_levels - 1)) is undefined for n_levels "
                          f"{self.levels}: give it")
        else:
            self.per_level_scale = 2.0
        interpolation = r.word("interpolation", "Linear", ("nearest", "linear", "smoothstep"))
        if interpolation != "linear":
            raise err(f"{where}.interpolation", f"{r.obj['interpolation']}: inshade lowers Linear interpolation "
                                                f"only")
        self.hash = r.word("hash", "CoherentPrime", ("coherentprime", "prime", "reversedprime", "rng", "baseconvert"))
        if self.hash not in GRID_HASHES:
            raise err(f"{where}.hash", f"{r.obj['hash']}: inshade lowers CoherentPrime, Prime and ReversedPrime")
        if r.boolean("fixed_point_pos", False):
            raise err(f"{where}.fixed_point_pos", "true is not supported (its fixed-point positions change the "
                                                  "forward pass of tiny-cuda-nn's fused kernel)")
        # read for the record only: it changes the backward pass (kernel_grid_backward), not the forward
        self.stochastic_interpolation = r.boolean("stochastic_interpolation", False)
        if n_dims not in (2, 3):
            raise err(where, f"a grid over {n_dims} input lanes: inshade lowers 2D and 3D grids (tiny-cuda-nn "
                             f"also has 4D)")
        try:
            self.grid_levels = grid_levels(n_dims, self.levels, self.base_resolution, self.per_level_scale,
                                           self.log2_hashmap_size, self.type)
        except GridLayoutError as exc:
            raise err(where, str(exc)) from None
        self.alignment = self.features
        self.out = self.levels * self.features

    @property
    def rows(self) -> int:
        return table_rows(self.grid_levels)

    def n_params(self) -> int:
        return self.rows * self.features

    def params_text(self) -> str:
        return (f"{self.type} grid: {self.rows} table rows x {self.features} features over {self.levels} levels "
                f"(rows per level {', '.join(str(lv.rows) for lv in self.grid_levels)})")

    def resolved(self):
        out = {"otype": "Grid", "type": self.type.capitalize(), "n_levels": self.levels,
               "n_features_per_level": self.features, "base_resolution": self.base_resolution,
               "per_level_scale": self.per_level_scale, "interpolation": "Linear",
               "hash": {"coherentprime": "CoherentPrime", "prime": "Prime", "reversedprime": "ReversedPrime"}[
                   self.hash]}
        if self.type == "hash":
            out["log2_hashmap_size"] = self.log2_hashmap_size
        return out


def dense_default_scale(base_resolution: int, levels: int) -> float:
    """grid.h create_grid_encoding_templated_2: std::exp(std::log(256.0f / base) / (n_levels - 1)),
    all in float (each function rounded once to float32)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        log = np.float32(math.log(np.float32(256.0) / np.float32(base_resolution)))
        ratio = np.float32(log / np.float32(levels - 1)) if levels > 1 else np.float32(np.nan)
    return float(np.float32(math.exp(ratio))) if np.isfinite(ratio) else float("nan")


class Composite(Encoding):
    """CompositeEncoding (encodings/composite.h): ``nested`` encodings over input lanes
    ``begins[i]`` .. ``begins[i] + nested[i].n_dims``, their outputs concatenated."""

    otype = "Composite"

    def __init__(self, where, n_dims, r: Reader):
        super().__init__(where, n_dims)
        err = r.ctx.error
        reduction = r.word("reduction", "Concatenation", ("concatenation", "sum", "product"))
        if reduction != "concatenation":
            raise err(f"{where}.reduction", f"{r.obj['reduction']}: inshade lowers Concatenation only")
        r.read.add("nested")
        nested = r.obj.get("nested")
        if not isinstance(nested, list) or not nested:
            raise err(f"{where}.nested", "must be a non-empty list of encodings")
        for i, n in enumerate(nested):
            if not isinstance(n, dict):
                raise err(f"{where}.nested[{i}]", "expected a JSON object")
        explicit = any("dims_to_encode_begin" in n for n in nested)
        total = sum(_dims(r.ctx, n, f"{where}.nested[{i}]") for i, n in enumerate(nested))
        if not explicit and total > n_dims:
            raise err(f"{where}.nested", f"the nested encodings encode {total} lanes, more than the {n_dims} "
                                         f"the composite takes")
        unspecified = None if explicit else n_dims - total
        self.nested, self.begins, offset = [], [], 0
        for i, cfg in enumerate(nested):
            w = f"{where}.nested[{i}]"
            if "n_dims_to_encode" in cfg:
                if "dims_to_encode_begin" in cfg:
                    offset = _dims(r.ctx, cfg, w, "dims_to_encode_begin")
                count = _dims(r.ctx, cfg, w)
            else:
                if unspecified is None:
                    raise err(f"{w}.n_dims_to_encode", "may be left out for one nested encoding only")
                count, unspecified = unspecified, None
            if offset + count > n_dims:
                raise err(w, f"encodes input lanes {offset}..{offset + count - 1}; the composite has {n_dims}")
            if count > 0:
                self.nested.append(parse_encoding(r.ctx, cfg, count, w, alignment=1, known=("n_dims_to_encode",
                                                                                         "dims_to_encode_begin")))
                self.begins.append(offset)
            offset += count
        if not self.nested:
            raise err(f"{where}.nested", "no nested encoding encodes any lane")
        # each nested output padded so that the next one starts at its required alignment
        so_far = 0
        for a, b in zip(self.nested, self.nested[1:]):
            a.set_padded(next_multiple(so_far + a.padded, b.alignment) - so_far)
            so_far += a.padded
        self.alignment = math.lcm(*(n.alignment for n in self.nested))

    @property
    def out(self) -> int:
        return sum(n.padded for n in self.nested) if hasattr(self, "nested") else 0

    @out.setter
    def out(self, value) -> None:   # the base class sets it before the nested exist
        pass

    @property
    def padded(self) -> int:
        return self.out

    def set_padded(self, width: int) -> None:   # the padding goes to the last nested encoding
        last = self.nested[-1]
        last.set_padded(width - (self.out - last.padded))

    def n_params(self) -> int:
        return sum(n.n_params() for n in self.nested)

    def params_text(self) -> str:
        return "; ".join(t for t in (n.params_text() for n in self.nested) if t)

    def resolved(self):
        return {"otype": self.otype, "nested": [{"n_dims_to_encode": n.n_dims, "dims_to_encode_begin": b,
                                                 **n.resolved()} for n, b in zip(self.nested, self.begins)]}


def _dims(ctx: Context, cfg: dict, where: str, key: str = "n_dims_to_encode") -> int:
    v = cfg.get(key, 0)
    if isinstance(v, bool) or not isinstance(v, int) or v < 0:
        raise ctx.error(f"{where}.{key}", f"expected a non-negative integer, got {v!r}")
    return v


def _nrc(where, n_dims, r: Reader) -> Composite:
    """encoding.cu's "OneBlobFrequency" / "NRC": TriangleWave on 3 lanes, OneBlob on 5, Identity on the rest."""
    cfg = {"otype": "Composite", "nested": [
        {"n_dims_to_encode": 3, "otype": "TriangleWave", "n_frequencies": r.uint("n_frequencies", 12)},
        {"n_dims_to_encode": 5, "otype": "OneBlob", "n_bins": r.uint("n_bins", 4)},
        {"otype": "Identity"}]}
    return Composite(where, n_dims, Reader(r.ctx, cfg, where))


def _grid(default_type):
    return lambda where, n_dims, r: Grid(where, n_dims, r, default_type)


# encoding.cu register_builtin_encodings (a case-insensitive map)
ENCODINGS = {
    "composite": Composite, "empty": Empty, "frequency": Frequency, "grid": _grid("hash"),
    "hashgrid": _grid("hash"), "tiledgrid": _grid("tiled"), "densegrid": _grid("dense"), "identity": Identity,
    "oneblob": OneBlob, "sphericalharmonics": SphericalHarmonics, "trianglewave": TriangleWave,
    "oneblobfrequency": _nrc, "nrc": _nrc,
}


def parse_encoding(ctx: Context, cfg, n_dims: int, where: str, alignment: int, known=()) -> Encoding:
    """create_encoding(n_dims_to_encode, encoding, alignment): otype "OneBlob" when absent; the
    result padded to ``alignment`` when it is not 0."""
    r = Reader(ctx, cfg, where)
    r.read.update(known)
    otype = cfg.get("otype", "OneBlob")
    if not isinstance(otype, str) or otype.lower() not in ENCODINGS:
        raise ctx.error(f"{where}.otype", f"{otype!r} is not a tiny-cuda-nn encoding "
                                          f"({', '.join(sorted(ENCODINGS))}; any case)")
    enc = ENCODINGS[otype.lower()](where, n_dims, r)
    r.done()
    if alignment > 0:
        enc.set_alignment(alignment)
    return enc


# --- networks --------------------------------------------------------------------------------

@dataclass
class Network:
    """FullyFusedMLP / CutlassMLP: bias-free layers; ``shapes`` the [rows, columns] of each weight
    matrix in parameter order (row-major), the last one's rows ``n_output_dims`` padded to 16."""
    otype: str
    n_input_dims: int
    n_output_dims: int
    n_neurons: int
    n_hidden_layers: int
    activation: str
    output_activation: str

    @property
    def padded_output(self) -> int:
        return next_multiple(self.n_output_dims, OUTPUT_ALIGNMENT)

    @property
    def shapes(self) -> list[tuple[int, int]]:
        if self.n_hidden_layers == 0:   # CutlassMLP only: one matrix
            return [(self.padded_output, self.n_input_dims)]
        return ([(self.n_neurons, self.n_input_dims)]
                + [(self.n_neurons, self.n_neurons)] * (self.n_hidden_layers - 1)
                + [(self.padded_output, self.n_neurons)])

    def n_params(self) -> int:
        return sum(a * b for a, b in self.shapes)

    def params_text(self) -> str:
        return (f"{self.otype}: weight matrices " + " + ".join(f"{a}x{b}" for a, b in self.shapes)
                + f" (the last one's {self.n_output_dims} output rows padded to {self.padded_output})")

    def resolved(self) -> dict:
        return {"otype": self.otype, "n_neurons": self.n_neurons, "n_hidden_layers": self.n_hidden_layers,
                "activation": ACTIVATION_NAMES[self.activation],
                "output_activation": ACTIVATION_NAMES[self.output_activation]}

    def check_precision(self, ctx: Context, dtype: str) -> None:
        """The FullyFusedMLP kernels exist in half precision only; with float32 parameters
        tiny-cuda-nn was built without them and runs the network as CutlassMLP (network.cu
        select_network), which takes any width, 0 hidden layers and every activation."""
        if self.otype != "FullyFusedMLP" or dtype != "float16":
            return
        if self.n_neurons not in FULLY_FUSED_WIDTHS:
            raise ctx.error("network.n_neurons", f"{self.n_neurons}: FullyFusedMLP takes 16, 32, 64 or 128")
        if self.n_hidden_layers < 1:
            raise ctx.error("network.n_hidden_layers", "FullyFusedMLP needs at least 1 hidden layer")
        if self.activation not in FULLY_FUSED_HIDDEN:
            raise ctx.error("network.activation", f"{ACTIVATION_NAMES[self.activation]}: FullyFusedMLP has no "
                                                  f"kernel for it as a hidden activation (CutlassMLP has)")


ACTIVATION_NAMES = {"none": "None", "relu": "ReLU", "leakyrelu": "LeakyReLU", "silu": "SiLU",
                    "exponential": "Exponential", "sine": "Sine", "sigmoid": "Sigmoid", "squareplus": "Squareplus",
                    "softplus": "Softplus", "tanh": "Tanh"}
NETWORKS = {"fullyfusedmlp": "FullyFusedMLP", "megakernelmlp": "FullyFusedMLP", "cutlassmlp": "CutlassMLP",
            "mlp": "CutlassMLP"}


def parse_network(ctx: Context, cfg, n_input_dims: int, n_output_dims: int) -> Network:
    """network.cu create_network: otype "MLP" (CutlassMLP) when absent, 128 neurons, 5 hidden
    layers, ReLU, output activation None."""
    r = Reader(ctx, cfg, "network")
    r.read.update(("n_input_dims", "n_output_dims"))
    otype = cfg.get("otype", "MLP")
    if not isinstance(otype, str) or otype.lower() not in NETWORKS:
        raise ctx.error("network.otype", f"{otype!r} is not a tiny-cuda-nn network (FullyFusedMLP, CutlassMLP; "
                                         f"any case)")
    net = Network(NETWORKS[otype.lower()], n_input_dims, n_output_dims, r.uint("n_neurons", 128),
                  r.uint("n_hidden_layers", 5), r.word("activation", "ReLU", ACTIVATIONS),
                  r.word("output_activation", "None", ACTIVATIONS))
    r.done()
    if net.n_hidden_layers > 0 and net.n_neurons < 1:
        raise ctx.error("network.n_neurons", "must be at least 1")
    return net


# --- the model -------------------------------------------------------------------------------

@dataclass
class Model:
    kind: str                 # NetworkWithInputEncoding | Network | Encoding
    n_input_dims: int
    n_output_dims: int
    encoding: Encoding
    network: Network | None
    ctx: Context

    def n_params(self) -> int:
        return (self.network.n_params() if self.network else 0) + self.encoding.n_params()

    def count_text(self) -> str:
        parts = []
        if self.network:
            parts.append(f"network {self.network.n_params()} ({self.network.params_text()})")
        if self.encoding.n_params():
            parts.append(f"then encoding {self.encoding.n_params()} ({self.encoding.params_text()})")
        return ", ".join(parts) or "no parameters"

    def resolved(self) -> dict:
        out = {"otype": self.kind, "n_input_dims": self.n_input_dims, "n_output_dims": self.n_output_dims,
               "encoding": self.encoding.resolved()}
        if self.network:
            out["network"] = self.network.resolved()
        return out


def parse_model(cfg, source: str, n_input_dims: int | None = None, n_output_dims: int | None = None) -> Model:
    """The model a config describes (see the module docstring for the three forms). ``n_input_dims``
    / ``n_output_dims`` from the command line; the config's own keys of those names must agree."""
    ctx = Context(source)
    if not isinstance(cfg, dict):
        raise ctx.error("(top level)", f"expected a JSON object, got {type(cfg).__name__}")
    if "encoding" not in cfg and "network" not in cfg and "otype" in cfg:   # a bare encoding or network config
        otype = cfg["otype"]
        inner = {k: v for k, v in cfg.items() if k not in ("n_input_dims", "n_output_dims")}
        key = "network" if isinstance(otype, str) and otype.lower() in NETWORKS else "encoding"
        cfg = {key: inner, **{k: cfg[k] for k in ("n_input_dims", "n_output_dims") if k in cfg}}
    elif "otype" in cfg and (not isinstance(cfg["otype"], str) or cfg["otype"].lower() != "networkwithinputencoding"):
        raise ctx.error("otype", f"{cfg['otype']!r}: a model config's otype is NetworkWithInputEncoding")
    ctx.ignored += [k for k in cfg if k not in MODEL_KEYS + SKIPPED_TOP_KEYS]
    n_in = _dim(ctx, cfg, "n_input_dims", n_input_dims, "--inputs")
    if n_in is None or n_in < 1:
        raise ctx.error("n_input_dims", "missing: give the model's input width as \"n_input_dims\" in the config "
                                        "or --inputs N")
    has_enc, has_net = "encoding" in cfg, "network" in cfg
    if not has_enc and not has_net:
        raise ctx.error("(top level)", "holds neither \"encoding\" nor \"network\"")
    if has_net:
        n_out = _dim(ctx, cfg, "n_output_dims", n_output_dims, "--outputs")
        if n_out is None or n_out < 1:
            raise ctx.error("n_output_dims", "missing: give the model's output width as \"n_output_dims\" in the "
                                             "config or --outputs M")
        enc_cfg = cfg["encoding"] if has_enc else {"otype": "Identity"}
        enc = parse_encoding(ctx, enc_cfg, n_in, "encoding", ENCODING_ALIGNMENT)
        enc.set_alignment(NETWORK_ALIGNMENT)
        net = parse_network(ctx, cfg["network"], enc.padded, n_out)
        kind = "NetworkWithInputEncoding" if has_enc else "Network"
        return Model(kind, n_in, n_out, enc, net, ctx)
    enc = parse_encoding(ctx, cfg["encoding"], n_in, "encoding", 0)
    n_out = _dim(ctx, cfg, "n_output_dims", n_output_dims, "--outputs")
    if n_out is not None and n_out != enc.padded:
        raise ctx.error("n_output_dims", f"{n_out}, but the encoding gives {enc.padded} lanes")
    return Model("Encoding", n_in, enc.padded, enc, None, ctx)


def _dim(ctx: Context, cfg: dict, key: str, given: int | None, option: str) -> int | None:
    v = cfg.get(key)
    if v is not None and (isinstance(v, bool) or not isinstance(v, int) or v < 0):
        raise ctx.error(key, f"expected a non-negative integer, got {v!r}")
    if given is not None and v is not None and given != v:
        raise ctx.error(key, f"{v}, but {option} says {given}")
    return given if given is not None else v
