"""inshade/progress.py: tqdm on a TTY, a line every ~10 s off it, silence when disabled; waiting on one long call."""
from __future__ import annotations

import io
import time

import pytest

from inshade.progress import Progress, default_interval, format_seconds, progress


class FakeClock:
    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


class Pipe(io.StringIO):
    def isatty(self):
        return False


class Tty(io.StringIO):
    def isatty(self):
        return True


def test_off_tty_lines_every_interval_with_postfix_elapsed_and_eta():
    clock, out = FakeClock(), Pipe()
    bar = progress(range(100), desc="train", stream=out, clock=clock, interval=30)
    assert bar.mode == "lines"
    seen = []
    for step in bar:
        seen.append(step)
        clock.now += 1.0   # 1 s per step
        bar.set_postfix(loss=f"{step / 100:.2f}")
    assert seen == list(range(100))     # the caller's loop is untouched
    lines = out.getvalue().splitlines()
    # a line after 30, 60, 90 s, and a closing one
    assert len(lines) == 4, lines
    assert lines[0] == "train: 30/100 it (30%), loss=0.29, 30.0 s elapsed, ETA 1:10"
    assert lines[1].startswith("train: 60/100 it (60%), loss=0.59, 1:00 elapsed, ETA")
    assert lines[-1] == "train: 100/100 it (100%), loss=0.99, done in 1:40"


def test_off_tty_short_work_is_silent():
    clock, out = FakeClock(), Pipe()
    for _ in progress(range(10), desc="quick", stream=out, clock=clock, interval=30):
        clock.now += 1.0
    assert out.getvalue() == ""


def test_off_tty_manual_updates_initial_and_unit_scale():
    clock, out = FakeClock(), Pipe()
    with Progress(total=4_000_000, desc="transfer (sdf)", unit="ray", unit_scale=True, stream=out,
                  clock=clock, interval=10, initial=1_000_000) as bar:
        clock.now += 10
        bar.update(1_000_000)
    lines = out.getvalue().splitlines()
    assert lines[0] == "transfer (sdf): 2.0M/4.0M ray (50%), 10.0 s elapsed, ETA 20.0 s"
    assert lines[1].startswith("transfer (sdf): 2.0M/4.0M ray (50%), done in")


def test_disabled_is_silent_everywhere():
    clock = FakeClock()
    for stream in (Pipe(), Tty()):
        bar = progress(range(5), stream=stream, clock=clock, interval=0.001, enabled=False)
        assert bar.mode == "off"
        for _ in bar:
            clock.now += 1.0
            bar.set_postfix(psnr="30.00")
        assert stream.getvalue() == ""


def test_tty_uses_tqdm():
    out = Tty()
    bar = progress(range(3), desc="tty bar", stream=out)
    assert bar.mode == "tty"
    from tqdm import tqdm
    assert isinstance(bar._bar, tqdm)
    assert list(bar) == [0, 1, 2]
    assert "tty bar" in out.getvalue()
    assert bar._bar.n == 3


def test_interval_from_environment(monkeypatch):
    monkeypatch.setenv("INSHADE_PROGRESS_INTERVAL", "5")
    assert default_interval() == 5.0
    monkeypatch.setenv("INSHADE_PROGRESS_INTERVAL", "nonsense")
    assert default_interval() == 10.0
    monkeypatch.delenv("INSHADE_PROGRESS_INTERVAL")
    assert default_interval() == 10.0


@pytest.mark.parametrize("seconds, text", [(12.34, "12.3 s"), (65, "1:05"), (3723, "1:02:03"),
                                           (float("inf"), "?")])
def test_format_seconds(seconds, text):
    assert format_seconds(seconds) == text


def test_first_draw_message_from_the_plan():
    """runtime.renderer: what a software renderer's first draw is about to JIT, derived from the plan."""
    from types import SimpleNamespace as NS

    from inshade.runtime.first_draw import first_draw_message

    def gen(*rows):
        return NS(plan=NS(rows=[NS(type=t, shape=s, storage=st) for t, s, st in rows]))

    net = gen(("frequency", "2->34", "-"), ("dense", "34->64", "inline"), ("relu", "64", "-"),
              ("dense", "64->64", "inline"), ("dense", "64->64", "inline"), ("dense", "64->3", "inline"))
    llvmpipe = "llvmpipe (LLVM 15.0.6, 256 bits)"
    assert first_draw_message([net], llvmpipe) == (
        "compiling a network of 4 dense layers up to 64 wide (inline) (llvmpipe JIT at the first draw: seconds to "
        "minutes; Mesa's shader cache keeps it for later runs)")
    mixed = gen(("dense", "66->128", "texture"), ("dense", "128->16", "inline"))
    assert first_draw_message([net, mixed], llvmpipe).startswith(
        "compiling 2 networks: 4 dense layers up to 64 wide (inline); 2 dense layers up to 128 wide (inline+texture)")
    assert first_draw_message([gen(("lookup_array", "2->4", "-"))], llvmpipe) is None
    # what this machine recorded: said, not promised
    assert first_draw_message([net], llvmpipe, 85.2, shader_cache=True) == (
        "drawing a network of 4 dense layers up to 64 wide (inline) (compiled before on this machine; Mesa's shader "
        "cache should make it quick)")
    assert first_draw_message([net], llvmpipe, 85.2, shader_cache=False).endswith("(llvmpipe JIT at the first draw; "
                                                                                 "1:25 last time)")


def test_waiting_speaks_only_for_long_waits_and_stops():
    """The watcher process prints while a call holds the GIL; nothing for a short wait."""
    import subprocess
    import sys
    import textwrap

    code = textwrap.dedent("""
        import sys, time
        from inshade.progress import waiting
        with waiting("compiling x", quiet=0.3, every=0.5) as w:
            time.sleep(float(sys.argv[1]))   # stands for a GL call holding the GIL
        print("done", round(w.seconds, 1))
    """)
    short = subprocess.run([sys.executable, "-c", code, "0.1"], capture_output=True, text=True, timeout=60)
    assert short.stderr == "" and short.stdout.startswith("done")
    long = subprocess.run([sys.executable, "-c", code, "1.6"], capture_output=True, text=True, timeout=60)
    lines = long.stderr.splitlines()
    assert 2 <= len(lines) <= 4 and all(x.startswith("inshade: still compiling x (") for x in lines), lines
    assert long.stdout.startswith("done 1.6")


@pytest.mark.parametrize("leave", ["from inshade.progress import stop_watchers; stop_watchers(); os._exit(130)",
                                   "os._exit(130)", "os.kill(os.getpid(), signal.SIGKILL)"],
                         ids=["ctrl-c", "os-exit", "killed"])
def test_a_watcher_never_outlives_its_process(leave):
    """Ctrl+C leaves through os._exit, which skips the watcher's stop: the watcher is stopped
    first, and one left behind by any other exit stops itself when its parent is gone, so nobody
    reading the command's stderr waits on a pipe it still holds."""
    import subprocess
    import sys
    import textwrap

    code = textwrap.dedent(f"""
        import os, signal, time
        from inshade.progress import waiting
        with waiting("compiling x", quiet=0.2, every=0.3):
            time.sleep(0.6)
            {leave}
    """)
    start = time.monotonic()
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.returncode in (130, -9) and time.monotonic() - start < 20, done.stderr
