"""Benchmarks: `inshade bench <name>` (speed goes here, not in timed tests).

Each benchmark module exposes ``add_arguments(parser)``, ``run(args) -> int`` and
``main(argv=None) -> int`` so the CLI can mount it as a subcommand (``inshade.cli.BENCHES``) or
run it standalone. Results are JSON + a markdown table + a plot in an output folder, with the
GL_RENDERER string and ratios measured side by side in the same run.
"""

import os
import platform


def machine(gl: dict) -> dict:
    """The "machine" record of every benchmark's JSON, from ``viewer.context.gl_info``."""
    return {"gl_renderer": gl["renderer"], "gl_version": gl["version"], "gl_vendor": gl["vendor"],
            "software_renderer": gl["software"], "cpu_count": os.cpu_count(), "python": platform.python_version()}
