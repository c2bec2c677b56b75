"""Fork server for tests/test_bad_inputs.py: one interpreter imports what ``inshade`` commands
import, then runs each case in a forked child of its own, as ``python -m inshade.cli`` would.

Usage (the test starts it with the environment a ``python -m inshade.cli`` subprocess would have)::

    python tests/bad_input_worker.py JOBS MEMORY_LIMIT TIMEOUT  < requests  > results

Requests are JSON lines, read to the end of standard input before anything runs::

    {"key": ..., "module": "inshade.cli" | "path": "script.py", "argv": [...], "cwd": ...,
     "stdout": FILE, "stderr": FILE, "timeout": SECONDS (optional)}

Each child is forked from this server, which has imported modules only (PREIMPORT: no GL context,
no torch, no Python thread; numpy's OpenBLAS threads are idle and OpenBLAS stops them at fork). It
sets ``RLIMIT_AS`` = MEMORY_LIMIT, changes to ``cwd``, points fd 0 at /dev/null and fds 1 and 2
at the two files, puts ``cwd`` first on ``sys.path`` (as ``-m`` does; a script's folder for
"path"), then leaves the server's loop and runs the module with ``runpy.run_module(...,
run_name="__main__", alter_sys=True)`` (as ``python -m`` runs it: its code as ``__main__``, with
``sys.argv[0]`` its file) at the top level of this script, so that the interpreter itself ends
it: ``SystemExit`` gives its status, an uncaught exception prints the interpreter's ``Traceback``
and status 1, atexit handlers and threads are finished and the interpreter finalized as at any exit.
At most JOBS children run at once; one still running after its timeout is killed (SIGKILL).
The server freezes its objects (``gc.freeze()``) before forking: a child's collections, and the
one at its exit, skip what it inherited (its exit takes ~0.07 s instead of ~0.2 s).

Results are JSON lines on standard output, one per request as it ends::

    {"key": ..., "rc": STATUS (negative: killed by that signal, as subprocess says), "timed_out": bool,
     "seconds": WALL}
"""
from __future__ import annotations

import gc
import importlib
import json
import os
import resource
import signal
import sys
import time

# What the commands of the corpus import lazily (python -X importtime: ~1.3 s of a ~1.5 s run).
# Modules only: nothing here creates a GL context or starts a thread. One that fails to import
# is left to the child (which then imports it and fails or not as `python -m` would).
PREIMPORT = ("argparse", "inshade", "inshade.technique", "inshade.bundle", "inshade.components", "inshade.shaders",
             "inshade.runtime.context", "inshade.scene.description", "inshade.runtime.headless",
             "inshade.runtime.renderer", "inshade.codegen", "inshade.envelope", "inshade.files", "inshade.extras",
             "inshade.progress", "inshade.convert.commands", "inshade.convert.shown_as", "inshade.convert.lowering",
             "inshade.geometry.shapes", "inshade.geometry.teapot", "inshade.geometry.gltf", "safetensors.numpy",
             "PIL.Image", "OpenEXR")


def _preimport() -> None:
    for name in PREIMPORT:
        try:
            importlib.import_module(name)
        except Exception:   # noqa: BLE001 (speed only: the child imports it again and reports what it gets)
            pass
    try:
        from inshade import technique
        from PIL import Image

        technique.techniques()   # imports the registered technique records (as the parser does)
        Image.init()             # Pillow's format plugins (imported on the first open of an unknown file)
    except Exception:   # noqa: BLE001
        pass


def _become(request: dict, memory_limit: int) -> None:
    """In the child: the process ``python -m MODULE ARGV`` would be, run from ``cwd``."""
    resource.setrlimit(resource.RLIMIT_AS, (memory_limit, memory_limit))
    os.chdir(request["cwd"])
    for fd, path, flags in ((0, os.devnull, os.O_RDONLY),
                            (1, request["stdout"], os.O_WRONLY | os.O_CREAT | os.O_TRUNC),
                            (2, request["stderr"], os.O_WRONLY | os.O_CREAT | os.O_TRUNC)):
        opened = os.open(path, flags, 0o644)
        os.dup2(opened, fd)
        os.close(opened)
    sys.path[0] = os.getcwd()   # `python -m`: the current folder first; a script: its folder
    if "path" in request:
        sys.path[0] = os.path.dirname(os.path.abspath(request["path"]))
    sys.argv = [request.get("path", "-m"), *request["argv"]]


def _serve(jobs: int, timeout: float) -> dict | None:
    """Run every request; return None in the server when all have ended, the request in a child."""
    requests = [json.loads(line) for line in sys.stdin if line.strip()]   # all of them, then EOF
    queue = list(reversed(requests))
    running: dict[int, tuple[dict, float, float]] = {}   # pid -> (request, start, deadline)
    killed: set[int] = set()
    while queue or running:
        while queue and len(running) < jobs:
            request = queue.pop()
            sys.stdout.flush()
            sys.stderr.flush()
            start = time.monotonic()
            pid = os.fork()
            if pid == 0:
                return request
            running[pid] = (request, start, start + float(request.get("timeout", timeout)))
        pid, status = os.waitpid(-1, os.WNOHANG)
        if pid == 0:
            now = time.monotonic()
            for child, (_, _, deadline) in running.items():
                if now > deadline and child not in killed:
                    os.kill(child, signal.SIGKILL)
                    killed.add(child)
            time.sleep(0.002)
            continue
        if pid not in running:
            continue
        request, start, _ = running.pop(pid)
        print(json.dumps({"key": request["key"], "rc": os.waitstatus_to_exitcode(status),
                          "timed_out": pid in killed, "seconds": round(time.monotonic() - start, 3)}), flush=True)
        killed.discard(pid)
    return None


if __name__ == "__main__":
    _jobs, _memory_limit, _timeout = int(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3])
    sys.path[0] = os.getcwd()   # not tests/: the server imports as `python -m` from its folder would
    _preimport()
    gc.collect()
    gc.freeze()   # what the server holds is left out of every child's collections
    _request = _serve(_jobs, _timeout)
    if _request is None:
        sys.exit(0)
    # a child from here on, at the top level: the interpreter ends it, as it ends `python -m`
    import runpy

    _become(_request, _memory_limit)
    if "path" in _request:
        runpy.run_path(_request["path"], run_name="__main__")
    else:
        runpy.run_module(_request["module"], run_name="__main__", alter_sys=True)
