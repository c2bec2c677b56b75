"""Sharded bakes: ground-truth data generation cut into deterministic shards, each cached as
safetensors, run in-process, on a local process pool or on a Ray cluster.

A bake is a module-level function ``fn(common, args) -> {name: numpy array}`` and a list of
``Shard`` s. ``common`` (the geometry, settings) is sent once per worker; ``Shard.args`` are the
shard's own inputs (its points, its offset in the random stream). A shard's result must depend
on ``common`` and its args only -- never on which worker, process or machine ran it -- so the
three runners give bit-identical results (the bake's function seeds every shard from its own
args; see techniques/prt/transfer.py for the PRT transfer bake).

Runners (``Executor``):

- in-process (default): shards run one after another in this process;
- ``--workers N``: a local ``concurrent.futures`` process pool with the *spawn* start method
  (forked torch thread pools and GL contexts do not survive ``fork``);
- ``--ray auto|ADDRESS``: tasks on a Ray cluster (``pip install 'inshade[cluster]'``), scheduled
  with ``num_gpus`` when the shard needs a GPU. ``auto`` joins the cluster this machine belongs
  to (``ray start``), or starts a local one when there is none. See docs/cluster.md.

Cache: with ``cache_dir`` every finished shard is written to ``cache_dir/<shard name>.safetensors``
as it arrives (atomically, by the driver only), and a rerun loads those instead of recomputing:
an interrupted bake resumes. The caller names the folder by everything the bake depends on.

This module needs numpy and safetensors only; torch is the bake function's business.
"""
from __future__ import annotations

import argparse
import json
import multiprocessing
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from inshade.files import atomic_files
from inshade.models.tensor_file import read_tensors

FORMAT = "inshade.bake_shard"


class BakeError(ValueError):
    """Bad executor option or an unusable shard cache; the message names the option or file."""


@dataclass(frozen=True)
class Shard:
    """One unit of work: ``name`` (unique in the bake; the cache file's stem), ``args`` (passed to
    the bake function), ``num_gpus`` (Ray resource request; 0 for CPU work)."""

    name: str
    args: dict = field(default_factory=dict)
    num_gpus: float = 0.0


@dataclass(frozen=True)
class Executor:
    """Where shards run: ``workers`` > 0 is a local process pool, ``ray`` ("auto" or a cluster
    address) a Ray cluster; neither is in-process."""

    workers: int = 0
    ray: str | None = None

    def __post_init__(self):
        if isinstance(self.workers, bool) or not isinstance(self.workers, int) or self.workers < 0:
            raise BakeError(f"--workers: must be an int >= 0, got {self.workers!r}")
        if self.workers and self.ray:
            raise BakeError("--workers and --ray: give one of them (Ray schedules its own workers)")
        if self.ray is not None and (not isinstance(self.ray, str) or not self.ray.strip()):
            raise BakeError(f"--ray: expected 'auto' or a cluster address (HOST:PORT or ray://HOST:PORT), "
                            f"got {self.ray!r}")

    @property
    def kind(self) -> str:
        return "ray" if self.ray else "pool" if self.workers else "in-process"

    @property
    def remote(self) -> bool:
        """True when shards run in other processes (their inputs are copied there)."""
        return self.kind != "in-process"


IN_PROCESS = Executor()


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``--workers N`` and ``--ray auto|ADDRESS`` (mutually exclusive)."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--workers", type=int, default=0,
                       help="bake shards on a local pool of N processes (0: in this process; results are "
                            "bit-identical either way)")
    group.add_argument("--ray", default=None, metavar="auto|ADDRESS",
                       help="bake shards on a Ray cluster: 'auto' joins this machine's cluster (or starts a "
                            "local one), ADDRESS a head node; needs pip install 'inshade[cluster]' "
                            "(docs/cluster.md)%(default).0s")


def executor_from_args(args: argparse.Namespace) -> Executor:
    return Executor(workers=getattr(args, "workers", 0) or 0, ray=getattr(args, "ray", None))


# ---------------------------------------------------------------------------------------------
# the shard cache

def _cache_path(cache_dir, shard: Shard) -> Path:
    return Path(cache_dir) / f"{shard.name}.safetensors"


def save_shard(path, name: str, result: dict) -> None:
    from safetensors.numpy import save_file

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    arrays = {k: np.ascontiguousarray(v) for k, v in result.items()}
    with atomic_files(path) as tmp:       # a crash leaves no half-written shard to resume from
        save_file(arrays, str(tmp), metadata={"format": FORMAT, "shard": name})


def load_shard(path, name: str) -> dict:
    header, arrays = read_tensors(
        path, "np", lambda exc: BakeError(f"{path}: unreadable bake shard ({exc}); delete it to recompute"))
    if header.get("format") != FORMAT or header.get("shard") != name:
        raise BakeError(f"{path}: not shard {name!r} of this bake ({json.dumps(header)}); delete it to recompute")
    return arrays


# ---------------------------------------------------------------------------------------------
# runners

def _check_result(shard: Shard, result) -> dict:
    if not isinstance(result, dict) or not all(isinstance(v, np.ndarray) for v in result.values()):
        raise BakeError(f"shard {shard.name}: the bake function must return a dict of numpy arrays, "
                        f"got {type(result).__name__}")
    return result


_WORKER: dict = {}


def _pool_init(fn, common) -> None:
    """Runs once in each spawned worker: the bake function and its common inputs stay there."""
    _WORKER["fn"], _WORKER["common"] = fn, common


def _pool_task(args: dict) -> dict:
    return _WORKER["fn"](_WORKER["common"], args)


def _ray_task(fn, common, args: dict) -> dict:
    return fn(common, args)


def run_shards(fn: Callable[[dict, dict], dict], shards: list[Shard], common: dict, cache_dir=None,
               executor: Executor = IN_PROCESS, on_done: Callable[[Shard], None] | None = None) -> list[dict]:
    """Results of ``fn(common, shard.args)`` for every shard, in the order of ``shards``.

    Shards already in ``cache_dir`` are loaded, the others run on ``executor`` and are cached as
    each finishes. ``fn`` must be importable by name (a module-level function) for the pool and
    Ray runners. ``on_done(shard)`` is called as each shard finishes (progress)."""
    names = [s.name for s in shards]
    if len(set(names)) != len(names):
        raise BakeError("shards: names must be unique (they name the cache files)")
    results: dict[str, dict] = {}
    todo = []
    for shard in shards:
        path = _cache_path(cache_dir, shard) if cache_dir is not None else None
        if path is not None and path.is_file():
            results[shard.name] = load_shard(path, shard.name)
            if on_done:
                on_done(shard)
        else:
            todo.append(shard)

    def finish(shard: Shard, result) -> None:
        results[shard.name] = _check_result(shard, result)
        if cache_dir is not None:
            save_shard(_cache_path(cache_dir, shard), shard.name, result)
        if on_done:
            on_done(shard)

    if todo:
        {"in-process": _run_in_process, "pool": _run_pool, "ray": _run_ray}[executor.kind](
            fn, todo, common, executor, finish)
    return [results[n] for n in names]


def _run_in_process(fn, shards, common, executor, finish) -> None:
    for shard in shards:
        finish(shard, fn(common, shard.args))


def _run_pool(fn, shards, common, executor, finish) -> None:
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=min(executor.workers, len(shards)), mp_context=ctx,
                             initializer=_pool_init, initargs=(fn, common)) as pool:
        pending = {pool.submit(_pool_task, s.args): s for s in shards}
        try:
            while pending:
                done, _ = wait(pending, return_when=FIRST_COMPLETED)
                for future in done:
                    finish(pending.pop(future), future.result())
        except BaseException:
            pool.shutdown(cancel_futures=True)     # a failed shard stops the bake; finished ones are cached
            raise


def _ray():
    try:
        import ray
    except ImportError:
        raise BakeError("--ray: Ray is not installed (pip install 'inshade[cluster]')") from None
    return ray


def _run_ray(fn, shards, common, executor, finish) -> None:
    ray = _ray()
    started = False
    if not ray.is_initialized():
        try:
            # "auto": the running cluster of this machine, else a fresh local one
            ray.init(address=None if executor.ray == "auto" else executor.ray, include_dashboard=False,
                     log_to_driver=False)
        except ConnectionError as exc:
            raise BakeError(f"--ray {executor.ray}: cannot reach the cluster ({exc})") from None
        started = True
    try:
        task = ray.remote(_ray_task)
        common_ref = ray.put(common)              # shipped to each node once, not once per shard
        pending = {task.options(num_cpus=1, num_gpus=s.num_gpus).remote(fn, common_ref, s.args): s
                   for s in shards}
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            for ref in done:
                finish(pending.pop(ref), ray.get(ref))
    finally:
        if started:
            ray.shutdown()


def describe(executor: Executor) -> str:
    """One line for logs: where the shards ran."""
    return {"in-process": "in-process", "pool": f"process pool of {executor.workers}",
            "ray": f"Ray ({executor.ray})"}[executor.kind]
