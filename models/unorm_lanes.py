"""The torch side of a table's u8 form (components/unorm.py): per lane value = offset + scale * q / 255.

A component mixes in ``UnormLanes`` and keeps float values (its parameter) as at any precision; at
u8 its lookup reads the unit values q / 255 (``unit``: straight through, so gradients reach the
float values as if unquantised) and decodes after its blend (``decode``: offset + scale * blend),
the order the shader uses. The range lives in the buffers ``scale`` / ``offset``, set by
``calibrate()`` (the values' per-lane min/max, or a given range: a loaded bundle's), and export
writes the codes of the values under that range: codes loaded from a bundle come back bit for bit
(their decoded values lie within 1e-5 steps of the codes).
"""
from __future__ import annotations

import numpy as np
import torch

from inshade.components.unorm import U8_LEVELS, checked_range, encode, lane_range


class UnormLanes:
    """Mixed into a torch.nn.Module with ``lanes`` values per row and a precision."""

    def unorm_values(self) -> torch.Tensor:
        """The float values the range covers, lanes last (all of the component's tables)."""
        raise NotImplementedError

    def set_precision(self, precision: str) -> None:
        self.precision = precision

    def to_u8(self) -> None:
        """Take the u8 form, the range covering the values as they are now."""
        self.set_precision("u8")
        self.calibrate()

    def calibrate(self, scale=None, offset=None) -> None:
        """Set the range per lane: given (scale, offset), else the values' min/max."""
        values = self.unorm_values().detach().cpu()
        lanes = values.shape[-1]
        if scale is None:
            scale, offset = lane_range(values.numpy())
        scale, offset = checked_range(scale, offset, lanes)
        for name, v in (("scale", scale), ("offset", offset)):
            if name in self._buffers:
                self._buffers[name] = torch.from_numpy(v.copy()).to(self._buffers[name].device)
            else:
                self.register_buffer(name, torch.from_numpy(v.copy()))

    def unit(self, values: torch.Tensor) -> torch.Tensor:
        """The unit values q / 255 of ``values`` under the range: q itself when nothing trains."""
        u = (values - self.offset) / self.scale
        q = torch.clamp(torch.round(u * U8_LEVELS), 0, U8_LEVELS) / U8_LEVELS
        return u + (q - u).detach() if values.requires_grad else q

    def decode(self, blend: torch.Tensor) -> torch.Tensor:
        return self.offset + self.scale * blend

    def codes(self, values: torch.Tensor) -> np.ndarray:
        """uint8 codes of ``values`` under the range."""
        return encode(values.detach().cpu().float().numpy(), self.scale.cpu().numpy(), self.offset.cpu().numpy())

    def unorm_range(self) -> dict:
        return {"scale": self.scale.cpu().numpy().copy(), "offset": self.offset.cpu().numpy().copy()}
