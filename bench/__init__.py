"""Benchmarks: `inshade bench <name>` (speed goes here, not in timed tests).

Each benchmark module declares its settings, run and suite entry once (``BENCH = Bench(...)``,
``inshade.bench.contract``) and exposes ``add_arguments(parser)``, ``main(argv=None) -> int`` and
``SUITE`` from it, so the CLI can mount it as a subcommand (``inshade bench NAME``) or run it
standalone. Results are JSON + a markdown table + a plot in an output folder, with the GL_RENDERER
string and ratios measured side by side in the same run, all written with the shared harness (``inshade.bench.harness``: machine record, clocks, interleaved A/B rounds, reports).
"""

from inshade.bench.harness import machine  # noqa: F401  (re-exported: every bench's machine record)
