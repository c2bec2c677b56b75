"""Inputs of the ground-truth transfer (techniques/prt/transfer.py): the error its callers catch and
the checks of points, counts and geometry (an SDF module or a trimesh.Trimesh) every entry point
runs before any ray is cast."""
from __future__ import annotations

import numpy as np
import torch


class TransferError(ValueError):
    """Bad input to transfer data generation; the message names the argument or file."""


def check_points(p, nrm, where: str = "points"):
    if not isinstance(p, torch.Tensor):
        p = torch.as_tensor(np.asarray(p, np.float32))
    if not isinstance(nrm, torch.Tensor):
        nrm = torch.as_tensor(np.asarray(nrm, np.float32))
    if p.ndim != 2 or p.shape[1] != 3:
        raise TransferError(f"{where}: positions must be [N, 3], got shape {tuple(p.shape)}")
    if nrm.shape != p.shape:
        raise TransferError(f"{where}: normals must match positions [N, 3], got {tuple(nrm.shape)} "
                            f"for {tuple(p.shape)}")
    p, nrm = p.detach().float(), nrm.detach().float()
    bad = ~(torch.isfinite(p).all(-1) & torch.isfinite(nrm).all(-1))
    if bad.any():
        raise TransferError(f"{where}: {int(bad.sum())} point(s) have NaN/inf position or normal "
                            f"(first at index {int(bad.nonzero()[0])})")
    length = nrm.norm(dim=-1)
    if (length < 1e-6).any():
        raise TransferError(f"{where}: normal at index {int((length < 1e-6).nonzero()[0])} is zero")
    return p, nrm / length[:, None]


def check_count(v, name: str) -> int:
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
        raise TransferError(f"{name}: must be a positive int, got {v!r}")
    return int(v)


def check_sdf(sdf):
    scene = getattr(sdf, "scene", None)
    if not callable(sdf) or scene is None or not all(hasattr(scene, a) for a in ("trace", "center", "radius")):
        raise TransferError(f"geometry: not an SDF module (needs __call__(p) and .scene with "
                            f"trace/center/radius): {type(sdf).__name__}")
    return scene


def check_mesh(mesh):
    import trimesh

    if not isinstance(mesh, trimesh.Trimesh):
        raise TransferError(f"geometry: expected a trimesh.Trimesh, got {type(mesh).__name__}")
    if len(mesh.faces) == 0:
        raise TransferError("mesh: has no faces")
    if not np.isfinite(mesh.vertices).all():
        raise TransferError("mesh: vertices contain NaN/inf")
    return mesh


def is_mesh(geometry) -> bool:
    try:
        import trimesh
    except ImportError:  # pragma: no cover
        return False
    return isinstance(geometry, trimesh.Trimesh)
