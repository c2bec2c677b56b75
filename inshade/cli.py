"""`inshade` command line: codegen, info, render, view, doctor, bench, train.

This module reads the command line and runs the command: the global options (-q, the GL backend
and device), the parser assembled from the command groups (inshade/commands/, one module per
group, and inshade/convert/commands.py), and the one-line error report. Bad input (a malformed
bundle, an unknown option value, a shader that does not compile, a missing GL capability) prints
one `inshade: error: ...` line and exits with status 2.
"""
from __future__ import annotations

import argparse
import logging
import os
import signal
import sys

from inshade.commands import codegen, doctor, info, mounted, render, view
from inshade.commands.common import ArgumentParser, UserError, int_at_least, one_line, user_errors
from inshade.commands.mounted import aliases, benches, run_module, trainers


def build_parser() -> argparse.ArgumentParser:
    """The whole command line: the global options, then each group's commands, in the order
    `inshade --help` lists them."""
    ap = ArgumentParser(prog="inshade", description="Run PyTorch-trained networks in OpenGL shaders. "
                        "An ASSET is a folder (scene.json and/or a bundle) or the name of a shipped one "
                        "(looked up in $INSHADE_ASSETS, then trained/), e.g. `inshade render prt_creature -o x.png`.")
    ap.add_argument("-q", "--quiet", action="store_true", help="only errors on stderr")
    _gl_options(ap, None)
    sub = ap.add_subparsers(dest="command", metavar="COMMAND", required=True)
    from inshade.convert.commands import add_parsers as add_convert_parsers

    codegen.add_parser(sub)
    add_convert_parsers(sub)   # convert and eval live with the converters
    info.add_parser(sub)
    render.add_parsers(sub)
    view.add_parser(sub)
    doctor.add_parser(sub)
    mounted.add_parsers(sub)
    for name, p in sub.choices.items():   # -q also after the command (`inshade render x -q ...`);
        if name not in ("bench", "train", *aliases()):   # SUPPRESS keeps a -q given before it
            p.add_argument("-q", "--quiet", action="store_true", default=argparse.SUPPRESS,
                           help="only errors on stderr")
        if name in GL_COMMANDS:
            _gl_options(p, argparse.SUPPRESS)
    return ap


# GL backend and device: global options (before the command, or after it for the commands that
# make a GL context; bench and train take them anywhere among their own options)
GL_COMMANDS = ("codegen", "render", "view", "doctor", "convert", "eval")
GL_OPTIONS = ("--gl-backend", "--gl-device")


_DEVICE_INDEX = "expected an EGL device index (0, 1, ...)"
_device_index = int_at_least(0, _DEVICE_INDEX, _DEVICE_INDEX)


def _gl_options(p, default) -> None:
    from inshade.runtime.context import BACKENDS

    p.add_argument("--gl-backend", choices=BACKENDS, default=default,
                   help="headless OpenGL: egl (default; GPUs and Mesa) or osmesa (Mesa's off-screen CPU "
                        "library, for where EGL cannot start); env INSHADE_GL_BACKEND")
    p.add_argument("--gl-device", type=_device_index, metavar="N", default=default,
                   help="EGL device to render on (`inshade doctor` lists them); env INSHADE_EGL_DEVICE")


def _split_gl_options(argv: list[str]) -> tuple[list[str], list[str]]:
    """(--gl-backend/--gl-device options, the other arguments) of a bench/train command line;
    a `--` ends the search."""
    gl, rest, i = [], [], 0
    while i < len(argv):
        arg = argv[i]
        if arg == "--":
            rest += argv[i:]
            break
        if arg in GL_OPTIONS:
            gl += argv[i:i + 2]
            i += 2
            continue
        (gl if arg.split("=", 1)[0] in GL_OPTIONS else rest).append(arg)
        i += 1
    return gl, rest


def _apply_gl_options(args) -> None:
    """Check the GL flags and make them the process's choice (context.select)."""
    backend, device = getattr(args, "gl_backend", None), getattr(args, "gl_device", None)
    if backend is None and device is None:
        return
    if getattr(args, "command", None) == "view":
        raise UserError("view: --gl-backend/--gl-device choose the headless context; a window renders on its "
                        "display's GPU (on a hybrid laptop: __NV_PRIME_RENDER_OFFLOAD=1 "
                        "__GLX_VENDOR_LIBRARY_NAME=nvidia inshade view)")
    from inshade.runtime.context import select

    select(backend, device)


def main(argv=None) -> int:
    """Run a command; Ctrl+C ends it quietly with status 130, a closed output pipe (`| head`)
    with status 141, neither with a traceback."""
    try:
        try:
            return _main(argv)
        finally:
            if sys.stdout is not None:
                sys.stdout.flush()   # a closed pipe shows here, where it is handled below
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        # Python's recipe: point stdout at devnull so the flush at exit does not fail again
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except (OSError, ValueError, AttributeError):   # a stdout without a file descriptor
            pass
        return 141


def _main(argv) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = build_parser()
    # `inshade bench mlp ...` / `inshade train X ...`: the module parses its own options
    # (so its --help is its own), after the global ones.
    lead = _leading_options(argv)
    rest = argv[len(lead):]
    if rest and rest[0] in aliases():
        rest = [*aliases()[rest[0]], *rest[1:]]
    tables = {"train": trainers, "bench": benches}
    if len(rest) >= 2 and rest[0] in tables and rest[1] in tables[rest[0]]():
        # the module parses its own options (and --help); the global ones are taken out first
        gl, module_rest = _split_gl_options(rest[2:])
        args = _global_parser().parse_args([*lead, *gl])
        args.module, args.rest, args.func = tables[rest[0]]()[rest[1]][0], module_rest, run_module
    else:
        args = ap.parse_args(argv)
    logging.basicConfig(level=logging.WARNING if args.quiet else logging.INFO,
                        format="inshade: %(message)s", stream=sys.stderr)
    logging.getLogger("OpenGL").setLevel(logging.WARNING)   # no "No OpenGL_accelerate module loaded"
    try:
        _apply_gl_options(args)
        return int(args.func(args) or 0)
    except user_errors() as e:
        print(f"inshade: error: {one_line(str(e))}", file=sys.stderr)
        return 2
    except ModuleNotFoundError as e:   # an optional extra that is not installed (a runtime-only install)
        if (e.name or "inshade").startswith("inshade"):
            raise
        from inshade.extras import missing_line

        command = " ".join(rest[:2]) if rest and rest[0] in tables else getattr(args, "command", None)
        print(f"inshade: error: {missing_line(e.name, command)}", file=sys.stderr)
        return 2
    except BrokenPipeError:   # stdout closed (`| head`): main() ends quietly
        raise
    except OSError as e:   # an input that cannot be read (permissions, a folder for a file, ...)
        where = f"{e.filename}: " if e.filename else ""
        print(f"inshade: error: {where}{one_line(str(e.strerror or e))}", file=sys.stderr)
        return 2


def _global_parser() -> argparse.ArgumentParser:
    """The options every command takes (for bench/train, whose modules parse the rest)."""
    ap = ArgumentParser(prog="inshade", add_help=False)
    ap.add_argument("-q", "--quiet", action="store_true")
    _gl_options(ap, None)
    return ap


def _leading_options(argv: list[str]) -> list[str]:
    """The global options before the command: -q, --gl-backend B, --gl-device N (or OPTION=VALUE)."""
    i = 0
    while i < len(argv):
        name = argv[i].split("=", 1)[0]
        if argv[i] in ("-q", "--quiet") or name != argv[i] and name in GL_OPTIONS:
            i += 1
        elif argv[i] in GL_OPTIONS:
            i += 2
        else:
            break
    return argv[:i]


def _interrupted(signum, frame) -> None:
    """Ctrl+C in the `inshade` executable: remove unfinished outputs and leave at once, status 130.
    Unwinding instead would release GL objects while the driver's threads may still be drawing
    them, which crashes llvmpipe now and then (SIGSEGV)."""
    from inshade.files import remove_temporaries
    from inshade.progress import stop_watchers

    stop_watchers()
    remove_temporaries()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError, AttributeError):
            pass
    os._exit(130)


def entry() -> None:
    """The `inshade` executable (``main`` in-process still turns Ctrl+C into status 130)."""
    signal.signal(signal.SIGINT, _interrupted)
    sys.exit(main())


if __name__ == "__main__":
    entry()
