"""A bench's entry in `inshade bench suite`: its command line per preset, and how its JSON reads as
summary rows next to the paper's claims.

Every bench module (``inshade bench NAME``: a technique's ``bench`` module, or a shared one in
``bench/``) declares ``SUITE = SuiteEntry(sizes, claims, headlines)``; the suite reads it from
the module it runs and names no bench itself. ``claim_row`` builds one summary row, ``ratio_verdict``
words a harness ``Ratio`` record (median, bounds, verdict).
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

PRESETS = ("cpu", "device")   # cpu: minutes on a 2-core machine (llvmpipe); device: one GPU


@dataclass(frozen=True)
class Sizing:
    """One bench's command line in a preset (without --out) and the wall time it should take."""
    argv: tuple[str, ...]
    budget_s: float


@dataclass(frozen=True)
class Claim:
    paper: str                    # short citation
    measure: str                  # what is compared
    says: str                     # the paper's number, in words
    value: float | None = None    # the paper's number, where there is one
    higher_better: bool = True    # False for times


@dataclass(frozen=True)
class SuiteEntry:
    """``sizes``: preset -> Sizing (a preset left out: the bench is not run in it); ``claims``: claim
    key -> Claim; ``headlines(result) -> rows``: the summary rows (``claim_row``) of the bench's JSON."""
    sizes: Mapping[str, Sizing]
    headlines: Callable[[Mapping], list[dict]]
    claims: Mapping[str, Claim] = field(default_factory=dict)

    def __post_init__(self):
        unknown = [p for p in self.sizes if p not in PRESETS]
        if unknown:
            raise ValueError(f"SuiteEntry.sizes: unknown preset {unknown[0]!r} (known: {', '.join(PRESETS)})")
        for preset, s in self.sizes.items():
            if not isinstance(s, Sizing) or not s.budget_s > 0:
                raise ValueError(f"SuiteEntry.sizes[{preset!r}]: expected a Sizing with a budget > 0, got {s!r}")
        if not callable(self.headlines):
            raise ValueError("SuiteEntry.headlines: expected a function of the bench's JSON result")


def claim_row(claims: Mapping[str, Claim], bench: str, key: str, ours: str, value: float | None = None,
              subject: str = "") -> dict:
    """One summary row: our number (``ours`` in words, ``value`` where there is one) against
    ``claims[key]``, and ours / paper where both are numbers."""
    c = claims[key]
    ratio = value / c.value if value is not None and c.value not in (None, 0.0) else None
    return {"bench": bench, "claim": key, "subject": subject, "paper": c.paper, "measure": c.measure,
            "paper_says": c.says, "paper_value": c.value, "higher_better": c.higher_better, "ours": ours,
            "ours_value": value, "ours_over_paper": ratio}


def _x(v: float | None) -> str:
    return "?" if v is None else f"{v:.2f}"   # the harness stores a non-finite ratio as None


def ratio_verdict(ratio: Mapping) -> str:
    return f"{_x(ratio['median'])}x ({_x(ratio['low'])}-{_x(ratio['high'])}, {ratio['verdict']})"
