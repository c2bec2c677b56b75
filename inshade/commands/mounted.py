"""`inshade bench NAME` and `inshade train NAME` (and a trainer's own top-level name, e.g.
`inshade compress`): commands whose module parses its own options, so its --help is its own."""
from __future__ import annotations

import argparse
import importlib

from inshade.bench import benches   # name -> (module, help) of every registered bench


def trainers() -> dict:
    """name -> (module, help) of every registered technique with a trainer."""
    from inshade import technique

    return {t.name: (t.train, t.train_help or t.summary) for t in technique.techniques() if t.train}


def aliases() -> dict:
    """command -> ("train", name): a technique's own top-level name for its trainer
    (``Technique.train_alias``, e.g. `inshade compress ...` runs a texture trainer)."""
    from inshade import technique

    return {t.train_alias: ("train", t.name) for t in technique.techniques() if t.train and t.train_alias}


def add_parsers(sub) -> None:
    """A trainer's own names, then `bench` and `train`."""
    for alias, (command, name) in aliases().items():
        p = sub.add_parser(alias, help=f"same as `inshade {command} {name}`",
                           description=f"Same as `inshade {command} {name}`; try `inshade {command} {name} --help`.")
        p.add_argument("rest", nargs=argparse.REMAINDER, help="its options")
        p.set_defaults(func=run_module, module=(trainers() if command == "train" else benches())[name][0])

    _mount(sub, "bench", benches(), "benchmarks (write JSON + markdown + plot)")
    _mount(sub, "train", trainers(), "build trained/ assets")


def _mount(sub, name: str, table: dict, help_: str) -> None:
    p = sub.add_parser(name, help=help_, description=help_)
    inner = p.add_subparsers(dest="target", metavar="NAME", required=True)
    for key, (module, text) in table.items():
        q = inner.add_parser(key, help=text, description=text)
        q.set_defaults(module=module)
        # arguments are parsed by the module itself (its deps are optional extras)
        q.add_argument("rest", nargs=argparse.REMAINDER, help="options of this command (try --help)")
    p.set_defaults(func=run_module)


def run_module(args) -> int:
    return importlib.import_module(args.module).main(args.rest)
