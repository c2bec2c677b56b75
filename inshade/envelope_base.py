"""What the parity envelope's rules share: its limits, a finding, the node a rule bounds, the table of
rules (one per component type, registered once), and the interval helpers.

The limits and the measurements behind them are described in inshade/envelope.py, which walks a
bundle through this table; the rules themselves live in the component folders
(components/<name>/envelope.py).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .bundle import Bundle, Node
from .components import registry
from .components.unorm import decode

TOL = 1e-5
PERIODIC_ARG_INPUT = 2.0 ** 7 * math.pi    # ~402: sin/cos of a bundle input
PERIODIC_ARG_COMPUTED = 128.0              # sin/cos/tri of a computed value
EXP_ARG = 80.0
DENSE_MAGNITUDE = 175.0                    # S / max(1, min|y|) where cancellation can break the rule
DENSE_MAGNITUDE_WARN = 2.0 ** 24 / 16      # ~1.05e6: one ulp of S >= 1/16
LOOKUP_GAIN = 50.0                         # gain / max(1, max|cell|), coordinate from a dense etc.
LOOKUP_GAIN_CHAINED = 200.0                # same, coordinate straight from another lookup array
GRID_GAIN = 100.0                          # sum_d scale * neighbour difference / max(1, max|feature|)
POW_ARG = 64.0                             # log2 of the largest |x^p| computed as exp2(p log2|x|)
POW_EXPONENT = 32.0                        # |p| there
POW_SQUARING = 32                          # integer |p| up to this: repeated squaring (lib/activations)

WARNING, NOTE = "warning", "note"


@dataclass(frozen=True)
class Finding:
    """One quantity outside (warning) or near/assumed about (note) the parity envelope."""

    level: str          # "warning" or "note"
    node: str           # node id (or input port name for range assumptions)
    quantity: str       # what was bounded, e.g. "sin argument |omega0 * x|"
    bound: float        # its bound over the input ranges
    threshold: float    # the envelope's limit for it (nan for pure notes)
    why: str            # one sentence: what breaks beyond the threshold

    def line(self) -> str:
        thr = "" if math.isnan(self.threshold) else f" > {self.threshold:.4g}"
        return f"{self.level}: {self.node}: {self.quantity} bound {self.bound:.4g}{thr}: {self.why}"


@dataclass
class Walk:
    """What the walk over a bundle's nodes carries from node to node."""

    bundle: Bundle
    findings: list[Finding]
    # per sin / cos / frequency node: the bound of |argument| of each GLSL call group, for codegen
    periodic_args: dict[str, list[float]] = field(default_factory=dict)
    lut_ids: set[str] = field(default_factory=set)     # lookup arrays met so far (a chained coordinate)


_SIN_WHY_INPUT = ("beyond 2^7 pi (n_freqs > 8 on [-1, 1]) GLSL/torch agreement depends on the "
                  "driver's sin argument reduction, outside what the parity suite covers")
_SIN_WHY_COMPUTED = ("an upstream discrepancy of ~1 ulp is multiplied by the argument: measured "
                     "~5.7e-8 * bound scaled error (1.4e-5 at 2^6 pi), past the 1e-5 rule")


@dataclass
class Site:
    """One node as its rule sees it: the interval of its (concatenated) input, whether that input is
    bit-identical on both sides, and where its findings go."""

    walk: Walk
    node: Node
    lo: np.ndarray
    hi: np.ndarray
    src_exact: bool

    @property
    def bundle(self) -> Bundle:
        return self.walk.bundle

    @property
    def params(self) -> dict:
        return self.node.params

    def tensor(self, slot: str) -> np.ndarray:
        """The node's tensor in float64, as the bounds are computed."""
        return self.bundle.tensor(self.node, slot).astype(np.float64)

    def table(self, slot: str) -> np.ndarray:
        """A table's values as the shader decodes them (a u8 table's codes through its range), float64."""
        if self.params.get("precision") != "u8":
            return self.tensor(slot)
        return decode(self.bundle.tensor(self.node, slot), self.tensor("scale"), self.tensor("offset")).astype(np.float64)

    def halves(self):
        """The two operands of a binary node: its input split at out_dim."""
        k = self.node.out_dim
        return (self.lo[:k], self.hi[:k]), (self.lo[k:], self.hi[k:])

    def warn(self, quantity: str, bound, threshold, why: str, level: str = WARNING) -> None:
        self.walk.findings.append(Finding(level, self.node.id, quantity, float(bound), float(threshold), why))

    def periodic(self, quantity: str, bound: float, check_input: bool = True) -> None:
        """A periodic argument's bound against the limit for an input (when checked) or a computed value."""
        if self.src_exact:
            if check_input and bound > PERIODIC_ARG_INPUT:
                self.warn(quantity, bound, PERIODIC_ARG_INPUT, _SIN_WHY_INPUT)
        elif bound > PERIODIC_ARG_COMPUTED:
            self.warn(quantity, bound, PERIODIC_ARG_COMPUTED, _SIN_WHY_COMPUTED)


Bounds = Callable[[Site], "tuple[np.ndarray, np.ndarray]"]


@dataclass(frozen=True)
class Rule:
    """A component type's envelope rule: its output bounds (and findings) from a site, and whether
    an input bit-identical on both sides stays so through it (both sides compute it exactly)."""

    bounds: Bounds
    keeps_exact: bool


# component type -> its rule (inshade/envelope.py loads the component folders' rules into it)
RULES: dict[str, Rule] = registry.entries("envelope")


def rule(*types: str, keeps_exact: bool = False) -> Callable[[Bounds], Bounds]:
    """Registers a function as the envelope rule of these component types; a type has one rule."""
    def register(fn: Bounds) -> Bounds:
        for t in types:
            registry.add("envelope", t, Rule(fn, keeps_exact), where=f"{fn.__module__}.{fn.__qualname__}")
        return fn
    return register


# --- interval helpers ----------------------------------------------------------------------

def sin_range(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact range of sin over [lo, hi], elementwise (float64)."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    out_lo = np.minimum(np.sin(lo), np.sin(hi))
    out_hi = np.maximum(np.sin(lo), np.sin(hi))
    with np.errstate(invalid="ignore"):
        # a maximum pi/2 + 2k pi inside [lo, hi]?  a minimum -pi/2 + 2k pi?
        has_max = np.floor((hi - math.pi / 2) / (2 * math.pi)) >= np.ceil((lo - math.pi / 2) / (2 * math.pi))
        has_min = np.floor((hi + math.pi / 2) / (2 * math.pi)) >= np.ceil((lo + math.pi / 2) / (2 * math.pi))
    wide = ~np.isfinite(lo) | ~np.isfinite(hi) | (hi - lo >= 2 * math.pi)
    out_hi = np.where(has_max | wide, 1.0, out_hi)
    out_lo = np.where(has_min | wide, -1.0, out_lo)
    return out_lo, out_hi


def mag(lo, hi) -> np.ndarray:
    return np.maximum(np.abs(lo), np.abs(hi))


def min_abs(lo, hi) -> np.ndarray:
    return np.where((lo <= 0) & (hi >= 0), 0.0, np.minimum(np.abs(lo), np.abs(hi)))
