"""The tail every trainer and bench shares: parse its options, run it, and turn the errors a user
can fix into one ``inshade: error: ...`` line and exit status 2.

A module that ``inshade train NAME`` / ``inshade bench NAME`` mounts defines ``add_arguments(parser)``
and ``run(args)`` (or ``run(args, argv)`` to record its command line), then::

    def main(argv=None) -> int:
        return command.main("inshade train NAME", __doc__, add_arguments, run, argv, errors=(MyError,))
"""
from __future__ import annotations

import argparse
import inspect
import sys
from collections.abc import Callable


def main(prog: str, doc: str | None, add_arguments: Callable, run: Callable, argv=None, *,
         errors: tuple = (), formatter=argparse.HelpFormatter) -> int:
    """Parse ``argv`` (default ``sys.argv[1:]``) with ``add_arguments``, call ``run``; an exception
    of ``errors`` (or a refused asset folder) becomes one ``inshade: error:`` line and exit status 2."""
    from inshade.asset_folder import OutputExistsError

    parser = argparse.ArgumentParser(prog=prog, description=(doc or "").strip().splitlines()[0] if doc else None,
                                     formatter_class=formatter)
    add_arguments(parser)
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(argv)
    takes_argv = len(inspect.signature(run).parameters) > 1
    try:
        return int((run(args, argv) if takes_argv else run(args)) or 0)
    except (OutputExistsError, *errors) as exc:
        print(f"inshade: error: {exc}", file=sys.stderr)
        return 2
