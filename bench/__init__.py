"""Benchmarks: `inshade bench <name>` (speed goes here, not in timed tests).

Each benchmark module declares its settings, run and suite entry once (``BENCH = Bench(...)``,
``inshade.bench.contract``) and exposes ``add_arguments(parser)``, ``main(argv=None) -> int`` and
``SUITE`` from it, so the CLI can mount it as a subcommand (``inshade bench NAME``) or run it
standalone. Results are JSON + a markdown table + a plot in an output folder, with the GL_RENDERER
string and ratios measured side by side in the same run, all written with the shared harness (``inshade.bench.harness``: machine record, clocks, interleaved A/B rounds, reports).
"""

from inshade.bench.harness import machine  # noqa: F401  (re-exported: every bench's machine record)

# The benches of shared machinery (not of one technique: a technique's bench is on its record,
# inshade/technique.py), one registration line each: name -> (module, the line `inshade bench
# --help` shows). Their modules are imported only when run (their deps are optional extras).
SHARED = {
    "mlp": ("inshade.bench.mlp", "MLP throughput: GLSL per storage mode vs torch CPU vs sgemm peak"),
    "export": ("inshade.bench.export", "inshade.export / convert: export + check time, ONNX import time, "
                                       "export peak memory"),
    "web": ("inshade.web.bench", "every shipped asset as a WebGL2 page in headless Chromium: page bytes, "
                                 "load time, frame time, PSNR vs inshade render"),
    "startup": ("inshade.bench.startup", "every shipped asset's first picture in a fresh process, cold and warm, "
                                         "per weight storage"),
    "precision": ("inshade.bench.precision", "every shipped asset's dense weights at f16 and i8: bytes, the twin's "
                                             "error, the render against f32"),
    "suite": ("inshade.bench.suite", "every bench, sized by --preset cpu|device, and a one-page summary "
                                     "against the papers (docs/bench/<renderer>/)"),
}


def benches() -> dict[str, tuple[str, str]]:
    """name -> (module, help) of every registered bench: the shared ones, then each technique's."""
    from inshade import technique

    return {**SHARED, **{t.name: (t.bench, t.bench_help or t.summary) for t in technique.techniques() if t.bench}}
