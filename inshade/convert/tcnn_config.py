"""A tiny-cuda-nn model as tiny-cuda-nn builds it from its JSON config: every encoding with the
defaults its factory fills in, its output width, its padding (how many lanes, holding which value,
where) and its parameter count; the network's weight matrices in the order they lie in the flat
parameter vector. Numbers only (no torch): the encodings are in tcnn_encodings/ (each registered
by its otypes, with the components computing it), the JSON reading in tcnn_json.py, and
inshade/convert/tcnn.py lowers the model onto bundle components; docs/tcnn.md cites the
tiny-cuda-nn source of every rule.

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

from dataclasses import dataclass

from .tcnn_encodings import Encoding, parse_encoding
from .tcnn_json import Context, Reader, next_multiple

__all__ = ["Context", "Encoding", "Model", "Network", "next_multiple", "parse_encoding", "parse_model",
           "parse_network"]

NETWORK_ALIGNMENT = 16          # FullyFusedMLP / CutlassMLP REQUIRED_ALIGNMENT()
OUTPUT_ALIGNMENT = 16           # the output layer's rows are padded to a multiple of this
ENCODING_ALIGNMENT = 8          # create_encoding's default alignment (encoding.h)
FULLY_FUSED_WIDTHS = (16, 32, 64, 128)
# the hidden activations the half-precision FullyFusedMLP kernels are instantiated for
# (src/fully_fused_mlp.cu inference_mixed_precision_impl: any other throws "Unsupported activation.")
FULLY_FUSED_HIDDEN = ("none", "exponential", "sigmoid", "relu", "leakyrelu", "squareplus", "softplus", "tanh")
ACTIVATIONS = ("none", "relu", "leakyrelu", "silu", "exponential", "sine", "sigmoid", "squareplus", "softplus",
               "tanh")
MODEL_KEYS = ("encoding", "network", "n_input_dims", "n_output_dims", "otype")
SKIPPED_TOP_KEYS = ("loss", "optimizer")   # tiny-cuda-nn's sample configs carry the training setup too


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
