"""The learnt-transfer network (Learnt Transfer, Dhawal et al. 2022): sigma(p, n) -> 16 SH coefficients of
transfer; its graph, the frame its inputs and outputs live in, its evaluation and its bundle.

Contract shared by training (techniques/prt/transfer_training.py), codegen and the PRT shaders:

- bundle kind ``"transfer"``; inputs ``position`` (3, semantic "position") and ``normal``
  (3, semantic "normal"); one output ``transfer`` (degree**2 lanes, semantic "sh_transfer");
- the position fed to the network is normalised to the unit ball of the geometry's bound:
  ``q = (p - center) * (1 / radius)`` (float32 reciprocal, computed once);
- the network's raw output times ``scale`` is the transfer vector
  ``T_k(p, n) = integral V(w) max(0, w.n) y_k(w) dw`` (real orthonormal SH, inshade/sh.py).
  With a tanh output the targets are divided by ``scale`` for training, because tanh cannot
  reach the unoccluded band-1 value 2pi/3 * sqrt(3/4pi) ~ 1.023;
- all of that lives in ``bundle.meta["render"]["transfer"]``:
  ``{"center": [x, y, z], "radius": r, "scale": s, "degree": 4}``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from inshade.bundle import Bundle
from inshade.geometry.sdf import f32

from inshade.components.elementwise.torch_twin import LeakyReLU
from inshade.components.encodings.torch_twin import Frequency
from inshade.models.graph import GraphModule
from inshade.models.registry import TORCH_COMPONENTS

KIND = "prt"


@dataclass(frozen=True)
class TransferFrame:
    """How positions are normalised and outputs scaled (bundle.meta["render"]["transfer"])."""

    center: tuple[float, float, float]
    radius: float
    scale: float = 1.0
    degree: int = 4

    def to_dict(self) -> dict:
        return {"center": [f32(c) for c in self.center], "radius": f32(self.radius),
                "scale": f32(self.scale), "degree": int(self.degree)}

    @classmethod
    def from_bundle(cls, bundle: Bundle) -> "TransferFrame":
        meta = (bundle.meta.get("render") or {}).get("transfer")
        if not isinstance(meta, dict):
            raise ValueError(f"{bundle.path}: render.transfer: missing (not a transfer bundle?)")
        return cls(tuple(float(c) for c in meta["center"]), float(meta["radius"]),
                   float(meta.get("scale", 1.0)), int(meta.get("degree", 4)))

    @property
    def inv_radius(self) -> float:
        return f32(1.0 / float(np.float32(self.radius)))

    def normalise(self, p: torch.Tensor) -> torch.Tensor:
        """(p - center) * (1 / radius), in float32 as the shader computes it."""
        return (p.float() - torch.tensor(self.center, dtype=torch.float32)) * self.inv_radius


def transfer_graph(width: int = 64, layers: int = 4, pos_freqs: int = 6, normal_freqs: int = 4,
                   degree: int = 4, output: str = "tanh", slope: float = 0.01) -> GraphModule:
    """Frequency-encoded position and normal -> ``layers`` hidden leaky-ReLU layers of ``width``
    -> degree**2 outputs (tanh or identity)."""
    if output not in ("tanh", "identity"):
        raise ValueError(f"output activation must be 'tanh' or 'identity', not {output!r}")
    g = GraphModule([("position", 3, "position"), ("normal", 3, "normal")])
    src = [g.add("enc_p", Frequency(pos_freqs), "position"), g.add("enc_n", Frequency(normal_freqs), "normal")]
    for i in range(layers):
        src = g.add(f"a{i}", LeakyReLU(slope), g.dense(f"l{i}", src, width))
    src = g.dense(f"l{layers}", src, degree * degree)
    if output == "tanh":
        src = g.add("out_act", TORCH_COMPONENTS["tanh"](), src)
    g.output("transfer", src, "sh_transfer")
    return g


def evaluate_transfer(net: GraphModule, frame: TransferFrame, p: torch.Tensor, n: torch.Tensor) -> torch.Tensor:
    """Transfer vectors [N, degree**2] at points p [N, 3] with unit normals n [N, 3]."""
    y = net(torch.cat([frame.normalise(p), n.float()], -1))
    return y * frame.scale if frame.scale != 1.0 else y


def export_transfer(net: GraphModule, frame: TransferFrame, out_dir, metrics: dict | None = None,
                    provenance: dict | None = None, name: str = "transfer", precision: str = "f32") -> Bundle:
    """Writes the bundle (kind "transfer", ``render.transfer`` = the frame) into ``out_dir``, its dense
    layers at ``precision`` (inshade/quantize.py)."""
    bundle = net.export(KIND, name, provenance=provenance or {}, metrics=metrics or {},
                        render={"transfer": frame.to_dict()})
    if precision != "f32":
        from inshade.quantize import quantized

        bundle = quantized(bundle, precision)
    bundle.save(out_dir)
    return bundle
