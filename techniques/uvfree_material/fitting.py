"""What both uvfree_material trainers share (procedural objects and meshes in train.py, glTF files in
gltf_train.py): area-weighted surface samples, the fit loop and the preview."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from inshade.geometry.mesh import mesh_uv

BUNDLE = "material"


class TrainError(ValueError):
    """Bad training input; the message names the file or option."""


def alias_table(weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vose's alias method: (prob [N] float64, alias [N] int64); draw i uniform, keep it with
    probability prob[i], else take alias[i]. Zero-weight entries are never drawn."""
    w = np.asarray(weights, np.float64)
    if w.ndim != 1 or not len(w) or not np.isfinite(w).all() or (w < 0).any() or w.sum() <= 0:
        raise TrainError("faces: triangle areas must be finite, non-negative and not all zero")
    n = len(w)
    scaled = w * (n / w.sum())
    prob, alias = np.ones(n), np.arange(n)
    small = [i for i in range(n) if scaled[i] < 1.0]
    large = [i for i in range(n) if scaled[i] >= 1.0]
    while small and large:
        s, g = small.pop(), large.pop()
        prob[s], alias[s] = scaled[s], g
        scaled[g] -= 1.0 - scaled[s]
        (small if scaled[g] < 1.0 else large).append(g)
    for i in small:   # float leftovers: keep
        prob[i] = 1.0 if w[i] > 0 else 0.0
    return prob, alias


class SurfaceSampler:
    """Area-weighted points (face, t0, t1) on a mesh and their uv."""

    def __init__(self, mesh):
        self.faces = np.asarray(mesh.faces, np.int64)
        uv = mesh_uv(mesh)
        # a mesh without uv (a glTF file without textures) has targets that do not vary over uv
        self.uv = uv if uv is not None else np.zeros((len(mesh.vertices), 2))
        self.prob, self.alias = alias_table(np.asarray(mesh.area_faces))

    def __call__(self, n: int, rng: np.random.Generator):
        i = rng.integers(0, len(self.prob), n)
        face = np.where(rng.random(n) < self.prob[i], i, self.alias[i])
        r0, r1 = rng.random(n), rng.random(n)
        s = np.sqrt(r0)
        t0, t1 = (1.0 - s).astype(np.float32), (s * (1.0 - r1)).astype(np.float32)
        t2 = 1.0 - t0.astype(np.float64) - t1
        corners = self.uv[self.faces[face]]                       # [n, 3, 2]
        uv = t0[:, None] * corners[:, 0] + t1[:, None] * corners[:, 1] + t2[:, None] * corners[:, 2]
        return face, t0, t1, uv


def fit(graph, batch, s: Settings, device, desc: str, progress=None) -> list:
    """Adam on the feature table (``s.lr``) and the decoder (``s.mlp_lr``), MSE, cosine decay to 2 %
    over ``s.steps``; ``batch(rng)`` gives each step's (inputs [n, 3] float32: face, t0, t1; targets
    [n, C] float32). Returns the loss every 50 steps."""
    from inshade.models.fit_loop import adam, cosine, fit as fit_steps

    table = graph.nodes["features"].table
    mlp = [q for n, q in graph.named_parameters() if not n.startswith("nodes.features.")]
    opt = adam([{"params": [table], "lr": s.lr}, {"params": mlp, "lr": s.mlp_lr}], betas=(0.9, 0.99), eps=1e-15)
    rng = np.random.default_rng(s.seed)
    history = []
    steps = s.steps

    def step_loss(step):
        x, y = batch(rng)
        x, y = torch.from_numpy(x).to(device), torch.from_numpy(y).to(device)
        return torch.mean((graph(x) - y) ** 2)

    def after(step, loss, bar):
        if step % 50 == 0 or step == steps - 1:
            history.append({"step": step, "mse": round(loss.item(), 7)})
            bar.set_postfix(mse=f"{loss.item():.5f}")

    fit_steps(opt, step_loss, steps, lr_factor=cosine(steps, 0.02), after_step=after, desc=desc, progress=progress)
    return history


def render_preview(out: Path) -> None:
    """preview.png: the asset's scene, split view (left reference, right decoded)."""
    from inshade.runtime.headless import render_scene, save_render

    image, info = render_scene(out, settings={"view": "split"})
    save_render(image, info, out / "preview.png")
    Path(f"{out / 'preview.png'}.json").unlink()   # a shipped picture: its sidecar would hold this machine's paths
