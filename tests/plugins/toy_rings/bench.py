"""`inshade bench toy_rings --out DIR`: the toy network evaluated in numpy over a SIZE x SIZE uv
grid, timed; numpy only. Its SUITE entry below is all `inshade bench suite` needs to size, run and
summarise it, like any technique's bench."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from inshade import command
from inshade.bench.entry import Claim, Sizing, SuiteEntry, claim_row
from inshade.bench.harness import machine, measure, write_report

from .train import weights


def add_arguments(parser):
    parser.add_argument("--out", default="bench-out/toy_rings", help="output folder")
    parser.add_argument("--size", type=int, default=64, help="uv grid side (default %(default)s)")
    parser.add_argument("--repeats", type=int, default=3, help="timed evaluations (default %(default)s)")
    return parser


def evaluate(size: int, seed: int = 0) -> np.ndarray:
    """[size, size, 3]: sin(W uv + b) at the pixel centres."""
    w = weights(seed)
    u, v = np.meshgrid((np.arange(size) + 0.5) / size, (np.arange(size) + 0.5) / size)
    return np.sin(np.stack([u, v], -1) @ w["l0.weight"].T + w["l0.bias"])


def run(args) -> int:
    timing = measure(lambda: evaluate(args.size), repeats=args.repeats)
    result = {"machine": machine(), "size": args.size, "timing": timing.to_dict(),
              "pixels_per_s": args.size ** 2 / max(timing.median, 1e-9)}
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    write_report(out, "toy_rings", result, f"# toy_rings\n\n{result['pixels_per_s']:.3g} pixels/s at {args.size}²\n",
                 echo=False)
    return 0


def main(argv=None) -> int:
    return command.main("inshade bench toy_rings", __doc__, add_arguments, run, argv)


# ---------------------------------------------------------------------------------------------
# `inshade bench suite`: this bench's command line per preset, and its headline rows against the paper

CLAIMS = {"rate": Claim("Sine rings (a toy), Sec. 1", "numpy evaluation of the 2 -> 3 sine network, pixels / s",
                        "a million pixels a second", 1e6)}


def headlines(r: dict) -> list[dict]:
    return [claim_row(CLAIMS, "toy_rings", "rate", f"{r['pixels_per_s']:.3g} pixels/s at {r['size']}²",
                      r["pixels_per_s"])]


SUITE = SuiteEntry(sizes={"cpu": Sizing(("--size", "16", "--repeats", "2"), 5),
                          "device": Sizing(("--size", "256"), 5)},
                   claims=CLAIMS, headlines=headlines)
