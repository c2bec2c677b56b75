"""A transfer dataset's bound, identity and file (techniques/prt/transfer.py ``build_dataset``): the
sphere the network's positions are normalised by, the digest of what the transfer depends on (part
of the cache key), and the safetensors file the samples and their transfer are kept in."""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import torch

from inshade.files import atomic_files

from inshade.techniques.prt.transfer_directions import DEGREE
from inshade.techniques.prt.transfer_inputs import TransferError, check_sdf, is_mesh


def geometry_bound(geometry) -> tuple[tuple[float, float, float], float]:
    """(center, radius) of the sphere the network's positions are normalised by: the SDF scene's
    bound, or a mesh's bounding-box centre and the distance to its farthest vertex."""
    if is_mesh(geometry):
        c = np.asarray(geometry.bounds, np.float64).mean(0)
        r = float(np.linalg.norm(np.asarray(geometry.vertices) - c, axis=-1).max())
        return tuple(float(x) for x in c), r
    scene = check_sdf(geometry)
    return tuple(float(x) for x in scene.center), float(scene.radius)


def geometry_digest(geometry) -> str:
    """sha256 of what the transfer depends on: mesh vertices + faces (+ the file's own normals where
    it has them), or the SDF scene (description tree, bound, trace settings) and any tensors of the
    SDF module (neural SDFs)."""
    h = hashlib.sha256()
    if is_mesh(geometry):
        h.update(b"mesh")
        h.update(np.ascontiguousarray(geometry.vertices, np.float64).tobytes())
        h.update(np.ascontiguousarray(geometry.faces, np.int64).tobytes())
        if "normal" in geometry.vertex_attributes:   # a file's own normals (a glTF's) are sampled, not derived
            h.update(np.ascontiguousarray(geometry.vertex_attributes["normal"], np.float64).tobytes())
        return h.hexdigest()
    scene = check_sdf(geometry)
    h.update(b"sdf")
    h.update(type(geometry).__name__.encode())
    h.update(repr(getattr(scene, "root", None)).encode())
    h.update(json.dumps({"center": list(scene.center), "radius": scene.radius,
                         "trace": dict(scene.trace)}, sort_keys=True).encode())
    if isinstance(geometry, torch.nn.Module):
        for name, t in sorted(geometry.state_dict().items()):
            h.update(name.encode())
            h.update(t.detach().cpu().contiguous().numpy().tobytes())
    return h.hexdigest()


TENSORS = ("position", "normal", "transfer", "heldout_position", "heldout_normal", "heldout_transfer")


def save_dataset(data: dict, path) -> Path:
    """Writes a dataset (tensors + JSON metadata in the safetensors header) atomically."""
    from safetensors.torch import save_file

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    meta = {k: v for k, v in data.items() if k not in TENSORS and k != "cached"}
    with atomic_files(path) as tmp:
        save_file({k: data[k].contiguous() for k in TENSORS if k in data}, str(tmp),
                  metadata={"format": "inshade.transfer_data", "meta": json.dumps(meta, sort_keys=True)})
    return path


def load_dataset(path) -> dict:
    """Reads a dataset written by ``save_dataset`` (TransferError naming the file if it is not one)."""
    from safetensors import safe_open

    path = Path(path)
    try:
        with safe_open(str(path), framework="pt") as f:
            header = f.metadata() or {}
            if header.get("format") != "inshade.transfer_data":
                raise TransferError(f"{path}: format: not an inshade transfer dataset")
            data = json.loads(header["meta"])
            for k in TENSORS:
                if k in f.keys():
                    data[k] = f.get_tensor(k).float()
    except TransferError:
        raise
    except Exception as exc:  # safetensors raises several types for corrupt files
        raise TransferError(f"{path}: unreadable transfer dataset ({exc})") from None
    missing = [k for k in TENSORS[:3] if k not in data]
    if missing:
        raise TransferError(f"{path}: {missing[0]}: missing")
    n = data["position"].shape[0]
    if data["normal"].shape != (n, 3) or data["transfer"].shape != (n, DEGREE * DEGREE):
        raise TransferError(f"{path}: transfer: shapes do not match ({n} points)")
    return data
