"""Torch's intra-op thread count for a block of work, restored after."""
from __future__ import annotations

import contextlib

import torch


@contextlib.contextmanager
def torch_threads(n: int | None):
    """Run torch ops on ``n`` intra-op threads (None or 0: leave torch's setting), restoring the
    setting after. Fits of small networks and lookups are many small ops: on a shared 2-core
    machine with other processes busy, a 2-thread torch.floor on 4096 values took 2 ms against
    28 us on one thread, and two spinning threads made each SDF fit step ~15x slower than one."""
    old = torch.get_num_threads()
    if n:
        torch.set_num_threads(int(n))
    try:
        yield
    finally:
        torch.set_num_threads(old)
