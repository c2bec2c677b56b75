"""The importance-sampling proxy's output activation: the torch twin (its formulas, and the proxy
lobe's sampling routine and density that read its lanes, are models/proxy_lobe.py)."""
from __future__ import annotations

from inshade.models.proxy_lobe import proxy_activation
from inshade.models.registry import Component, register


@register
class ProxyParams(Component):
    type = "proxy_params"

    def __init__(self, isotropic: bool = False, alpha_min: float = 0.01):
        super().__init__()
        self.isotropic, self.alpha_min = bool(isotropic), float(alpha_min)

    def params(self):
        return {"isotropic": self.isotropic, "alpha_min": self.alpha_min}

    def forward(self, x):
        return proxy_activation(x, self.isotropic, self.alpha_min)
