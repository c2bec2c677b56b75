"""Training checkpoints: a safetensors file (data only, nothing a loader executes) holding a run's tensors, written
atomically, with the configuration they belong to. Resuming with another configuration is a
ValueError naming the first differing field: another run's weights would be silent garbage."""
from __future__ import annotations

import json
from pathlib import Path

from inshade.files import atomic_files
from inshade.models.tensor_file import read_tensors


def write_checkpoint(path, kind: str, tensors: dict, config: dict, **meta) -> None:
    """``tensors`` (name -> torch tensor) and ``meta`` (str values) under format ``inshade.<kind>_checkpoint``."""
    from safetensors.torch import save_file

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    header = {"format": f"inshade.{kind}_checkpoint", "config": json.dumps(config, sort_keys=True),
              **{k: str(v) for k, v in meta.items()}}
    with atomic_files(path) as tmp:
        save_file({k: v.detach().cpu().contiguous() for k, v in tensors.items()}, str(tmp), metadata=header)


def read_checkpoint(path, kind: str, config: dict, hint: str) -> tuple[dict, dict]:
    """(tensors, metadata) of a checkpoint of this ``kind`` and ``config``; ``hint`` ends the
    config-mismatch message (how to start over)."""
    path = Path(path)
    header, tensors = read_tensors(path, "pt", lambda exc: ValueError(f"{path}: unreadable checkpoint ({exc}); {hint}"))
    if header.get("format") != f"inshade.{kind}_checkpoint":
        raise ValueError(f"{path}: format: not a {kind} checkpoint")
    saved = json.loads(header.get("config", "{}"))
    if saved != config:
        key = sorted(k for k in set(saved) | set(config) if saved.get(k) != config.get(k))[0]
        raise ValueError(f"{path}: config.{key}: the checkpoint has {saved.get(key)!r}, this run "
                         f"{config.get(key)!r} ({hint})")
    return tensors, header
