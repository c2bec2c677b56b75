"""Surface samples for the ground-truth transfer (techniques/prt/transfer.py).

Surface samples: meshes with ``trimesh.sample.sample_surface`` (area weighted) and barycentric-
interpolated, normalised vertex normals (what the rasteriser interpolates). SDFs: marching cubes
over the bound, area-weighted samples of that mesh, Newton-projected onto the zero set, kept inside
the bound sphere, normals by the SDF's own estimator (``sdf.normals`` if it has one, else the
central differences of ``models.sdf.normals``, as the shader computes them: n is a network input).

SDF evaluations run on the caller's ``device``; the samples come back on the CPU.
"""
from __future__ import annotations

import copy

import numpy as np
import torch

from inshade.techniques.prt.transfer_inputs import TransferError, check_count, check_mesh, check_sdf


def _sdf_normals(sdf, p: torch.Tensor) -> torch.Tensor:
    own = getattr(sdf, "normals", None)
    if callable(own):
        return own(p)
    from inshade.models.sdf import normals

    return normals(sdf, p)


def _eval_chunked(sdf, p: torch.Tensor, chunk: int = 1 << 18, device=None) -> torch.Tensor:
    """sdf(p) chunk by chunk, evaluated on ``device`` (default p's), returned on p's device."""
    with torch.no_grad():
        return torch.cat([sdf(p[i:i + chunk].to(device or p.device)).to(p.device)
                          for i in range(0, p.shape[0], chunk)])


def sdf_on_device(sdf, device: torch.device):
    """The SDF module with its tensors on ``device``: itself when they are there already (or it has
    none, as an analytic SdfModule), else a moved copy (the caller's module stays where it is)."""
    if not isinstance(sdf, torch.nn.Module):
        return sdf
    probe = torch.empty(0, device=device).device        # "cuda" -> "cuda:<current>", as tensors report it
    tensors = [*sdf.parameters(), *sdf.buffers()]
    if all(t.device == probe for t in tensors):
        return sdf
    return copy.deepcopy(sdf).to(probe)


def sample_sdf_surface(sdf, n_points: int, seed: int = 0, resolution: int = 128, newton: int = 4,
                       device="cpu"):
    """``n_points`` surface samples (p [N, 3], unit normals [N, 3], float32) of an SDF module,
    area weighted: marching cubes at ``resolution`` over the bound's box, area-weighted samples of
    that mesh, ``newton`` Newton steps p -= d * n onto the zero set (n: the SDF's normal estimator,
    not autograd: hard booleans and box corners have NaN autograd gradients); only points inside
    the bound sphere with |d| < hit_eps are kept. SDF evaluations run on ``device``; the samples
    come back on the CPU."""
    import trimesh
    from skimage.measure import marching_cubes

    scene = check_sdf(sdf)
    n_points = check_count(n_points, "n_points")
    device = torch.device(device)
    sdf = sdf_on_device(sdf, device)
    c = np.asarray(scene.center, np.float64)
    r = float(scene.radius)
    axis = np.linspace(-r, r, resolution)
    grid = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), -1).reshape(-1, 3) + c
    d = _eval_chunked(sdf, torch.from_numpy(grid).float(), device=device).reshape(resolution, resolution, resolution)
    d = d.numpy()
    if not (d.min() < 0.0 < d.max()):
        raise TransferError(f"{getattr(scene, 'path', None) or 'sdf'}: no surface inside the bound "
                            f"(distances in [{d.min():.3g}, {d.max():.3g}])")
    step = 2.0 * r / (resolution - 1)
    verts, faces, _, _ = marching_cubes(d, 0.0, spacing=(step, step, step))
    mesh = trimesh.Trimesh(verts + (c - r), faces, process=False)
    hit_eps = float(scene.trace["hit_eps"])
    rng = np.random.default_rng(seed)
    kept_p, kept_n, have = [], [], 0
    for _ in range(8):              # top up: some samples land outside the bound or off the surface
        want = int((n_points - have) * 1.3) + 64
        pts, _ = trimesh.sample.sample_surface(mesh, want, seed=rng)
        p = torch.from_numpy(np.asarray(pts, np.float32)).to(device)
        with torch.no_grad():
            for _ in range(newton):
                p = p - sdf(p)[:, None] * _sdf_normals(sdf, p)
            dist = sdf(p).cpu()
            nrm = _sdf_normals(sdf, p).cpu()
        p = p.cpu()
        inside = (p.double() - torch.from_numpy(c)).norm(dim=-1) < r
        ok = inside & (dist.abs() < hit_eps) & torch.isfinite(nrm).all(-1) & torch.isfinite(p).all(-1)
        kept_p.append(p[ok])
        kept_n.append(nrm[ok])
        have += int(ok.sum())
        if have >= n_points:
            break
    if have < n_points:
        raise TransferError(f"sdf: only {have} of {n_points} surface samples projected onto the surface")
    return torch.cat(kept_p)[:n_points].contiguous(), torch.cat(kept_n)[:n_points].contiguous()


def sample_mesh_surface(mesh, n_points: int, seed: int = 0):
    """Area-weighted samples (p [N, 3], unit normals [N, 3], float32) of a trimesh.Trimesh; the
    normals are the barycentric interpolation of the vertex normals, normalised."""
    import trimesh

    mesh = check_mesh(mesh)
    n_points = check_count(n_points, "n_points")
    pts, fi, bary = trimesh.sample.sample_surface(mesh, n_points, seed=int(seed), return_barycentric=True)
    vn = np.asarray(mesh.vertex_normals, np.float64)[mesh.faces[fi]]        # [N, 3 corners, 3]
    nrm = np.einsum("nc,ncx->nx", np.asarray(bary, np.float64), vn)
    length = np.linalg.norm(nrm, axis=-1, keepdims=True)
    # a degenerate interpolation (opposing vertex normals) falls back to the face normal
    nrm = np.where(length > 1e-8, nrm / np.maximum(length, 1e-30), mesh.face_normals[fi])
    return torch.from_numpy(np.asarray(pts, np.float32)), torch.from_numpy(nrm.astype(np.float32))
