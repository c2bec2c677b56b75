"""The neural material in torch: latent pyramid, encoder (training only), decoders with learned
shading frames, importance-sampling decoders; built from bundle components so that the exported
bundles are exactly what was trained (models/ twins, codegen/ emitters).

Networks (Real-Time Neural Appearance Models §2; sizes from the paper):
- ``latents``: ``latent_pyramid`` (u, v, level) -> z (8), bilinear within one level, repeat wrap;
- ``decoder_WxD``: (z, light, view) -> ``shading_frames`` (2 frames, 12 lanes) ++ z -> MLP
  (2x16, 2x32, 3x64, ReLU) -> log(1 + f cos); exported with an ``expm1`` node, so the bundle
  outputs f cos itself;
- ``sampler``: (z, view) -> MLP 3x32 -> ``proxy_params`` (9 proxy parameters);
  ``sampler_isotropic``: the same with the isotropic proxy (3 raw outputs), the paper's baseline;
- ``encoder`` (training only): k(x) (the material's per-texel parameters, LEAN-prefiltered for
  coarse levels) -> MLP 2x64 -> z.

``export_graphs`` gives the bundle graphs of a trained material; ``decoder_loss`` and
``sampler_loss`` are what the networks are fit with (§3.5).
"""
from __future__ import annotations

import math

import torch

from inshade.models.graph import GraphModule
from inshade.models.proxy_lobe import cosine_direction
from inshade.models.registry import TORCH_COMPONENTS

LATENT = 8
DECODER_SIZES = {"2x16": (16, 16), "2x32": (32, 32), "3x64": (64, 64, 64)}
SAMPLER_WIDTHS = (32, 32, 32)
ENCODER_WIDTHS = (64, 64)


def _component(type_name: str, **params):
    return TORCH_COMPONENTS[type_name](**params)


def mlp(g: GraphModule, src, widths, out: int, prefix: str = "l") -> str:
    """(dense -> relu) per width, then a dense layer of ``out``; returns the last node."""
    for i, w in enumerate(widths):
        src = g.dense(f"{prefix}{i}", src, w)
        src = g.add(f"{prefix}a{i}", _component("relu"), src)
    return g.dense(f"{prefix}{len(widths)}", src, out)


def decoder(widths) -> GraphModule:
    """(z, light, view) -> log(1 + f cos) [3], without the final expm1 (``finish_decoder`` adds it)."""
    g = GraphModule([("z", LATENT, "latent"), ("light", 3, "direction"), ("view", 3, "direction")])
    frames = g.add("frames", _component("shading_frames", latent=LATENT, frames=2), ["z", "light", "view"])
    last = mlp(g, ["z", frames], widths, 3)
    g.output("log_brdf", last, "log1p_rgb")
    return g


def finish_decoder(g: GraphModule) -> GraphModule:
    """The exported decoder: the trained graph + expm1, outputting f cos (linear RGB)."""
    last = g.outputs[0][1]
    node = g.add("expm1", _component("expm1"), last)
    g.outputs = [("brdf", node, "linear_rgb")]
    return g


def sampler(isotropic: bool = False) -> GraphModule:
    """(z, view) -> the 9 proxy-lobe parameters (models/proxy_lobe.py order)."""
    g = GraphModule([("z", LATENT, "latent"), ("view", 3, "direction")])
    last = mlp(g, ["z", "view"], SAMPLER_WIDTHS, 3 if isotropic else 9)
    proxy = g.add("proxy", _component("proxy_params", isotropic=isotropic), last)
    g.output("proxy", proxy, "proxy_lobe")
    return g


def encoder(inputs: int) -> torch.nn.Sequential:
    layers, width = [], inputs
    for w in ENCODER_WIDTHS:
        layers += [torch.nn.Linear(width, w), torch.nn.ReLU()]
        width = w
    layers.append(torch.nn.Linear(width, LATENT))
    return torch.nn.Sequential(*layers)


def latents_graph(pyramid) -> GraphModule:
    g = GraphModule([("uvl", 3, "uv_level")])
    node = g.add("pyramid", pyramid, "uvl")
    g.output("z", node, "latent")
    return g


class NeuralMaterial(torch.nn.Module):
    """Everything trained for one material. ``pyramid`` is created at phase 2 (from the encoder)."""

    def __init__(self, encoder_inputs: int, resolution: int, levels: int):
        super().__init__()
        self.resolution, self.levels = int(resolution), int(levels)
        self.encoder = encoder(encoder_inputs)
        self.decoders = torch.nn.ModuleDict({name: decoder(w) for name, w in DECODER_SIZES.items()})
        self.samplers = torch.nn.ModuleDict({"sampler": sampler(False), "sampler_isotropic": sampler(True)})
        self.pyramid = None

    def make_pyramid(self, levels_data: list[torch.Tensor]):
        """The latent pyramid initialised from per-level latents [N >> k, N >> k, 8]."""
        cls = TORCH_COMPONENTS["latent_pyramid"]
        self.pyramid = cls.from_arrays([t.detach().cpu().numpy() for t in levels_data], precision="f16")
        return self.pyramid


def export_graphs(model: NeuralMaterial) -> dict[str, GraphModule]:
    """The bundle graphs of a trained material (on the CPU), by asset folder: the latent pyramid,
    the decoders with their expm1 and the samplers."""
    graphs = {"latents": latents_graph(model.pyramid)}
    for name, dec in model.decoders.items():
        graphs[f"decoder_{name}"] = finish_decoder(dec)
    graphs.update(model.samplers.items())
    return graphs


# ---------------------------------------------------------------------------------------------
# losses

def decoder_loss(model: NeuralMaterial, z, light, view, target) -> tuple[torch.Tensor, dict]:
    x = torch.cat([z, light, view], -1)
    goal = torch.log1p(torch.clamp(target, min=0))
    losses = {name: (dec(x) - goal).abs().mean() for name, dec in model.decoders.items()}
    return sum(losses.values()), {k: float(v.detach()) for k, v in losses.items()}


def sampler_loss(model: NeuralMaterial, z, view, samples: int, gen) -> tuple[torch.Tensor, dict]:
    """KL(decoder || proxy) up to a constant, per (z, view): -E_m[(p / m) log q] with directions
    from the mixture m = (q + cosine) / 2, p the 3x64 decoder's luminance normalised per pair by
    its own estimate; latents and the decoder detached (§3.5)."""
    from inshade.models.proxy_lobe import proxy_pdf, proxy_sample

    z = z.detach()
    n = z.shape[0]
    zz = z.repeat_interleave(samples, 0)
    vv = view.repeat_interleave(samples, 0)
    u = torch.rand(n * samples, 3, generator=gen).to(z.device)
    dec = model.decoders["3x64"]
    out = {}
    total = 0.0
    for name, smp in model.samplers.items():
        params = smp(torch.cat([z, view], -1)).repeat_interleave(samples, 0)
        with torch.no_grad():
            from_proxy = proxy_sample(params.detach(), vv, u)
            cos = cosine_direction(u[:, 1].double(), u[:, 2].double()).float()
            pick = (torch.arange(n * samples, device=z.device) % 2 == 0)[:, None]
            light = torch.where(pick, from_proxy, cos)
            light = torch.nn.functional.normalize(light, dim=-1)
            f = torch.expm1(dec(torch.cat([zz, light, vv], -1))).clamp(min=0).mean(-1)
            f = torch.where(light[:, 2] > 0, f, torch.zeros_like(f))
            q_det = proxy_pdf(params.detach(), vv, light)
            m = 0.5 * q_det + 0.5 * torch.clamp(light[:, 2], min=0) / math.pi
            w = torch.where(m > 0, f / m.clamp(min=1e-12), torch.zeros_like(f)).reshape(n, samples)
            w = w / w.mean(1, keepdim=True).clamp(min=1e-12)
        q = proxy_pdf(params, vv, light).clamp(min=1e-12)
        loss = -(w.reshape(-1) * torch.log(q)).mean()
        out[name] = float(loss.detach())
        total = total + loss
    return total, out
