"""The radiance-field application: instant-NGP's NeRF trained here with the torch twin from its own
rendered views of a procedural scene (radiance_field_scene.py), shipped as
trained/hash_grid_radiance_field and ray marched in the shader (radiance_field_render.py).

Data: the scene rendered at ``train_views`` cameras over the upper hemisphere (``train_size``
pixels a side) and ``heldout_views`` cameras between them (``heldout_size``): the ground truth.

One step (occupancy-guided sampling, as instant-NGP):
  - rays drawn uniformly over every training pixel, as many as make about ``batch`` network
    evaluations (the count follows the samples per ray of the steps before);
  - samples: the march's own positions t0 + (i + 0.5) dt, only those in occupied cells of the
    training density grid (radiance_field_march.candidates);
  - a density-only pass without gradients finds where each ray's transmittance falls under STOP
    (the march stops there too); the samples before it are evaluated with gradients and composited
    over the background (radiance_field_march.composite); loss: MSE against the pixel, plus
    ``empty_weight`` x the mean optical thickness of a step at random points of unoccupied cells
    (so a march that evaluates every sample sees what the skipping one sees);
  - Adam with instant-NGP's split (network.optimizer: tables and MLP), cosine decay to 5%;
  - every ``occupancy_every`` steps the density grid (``occupancy_resolution``^3 cells) takes the
    density at one random point in every cell: grid = max(0.95 grid, sigma) (instant-NGP's update);
    a cell is occupied while grid x dt exceeds min(``occupancy_threshold``, the grid's mean)
    (instant-NGP's rule: early on, the denser half), grown by one cell. The grid starts full.

The shipped occupancy grid: the trained density's max over a 4^3 lattice in each cell, the same
threshold, grown by one cell (the lattice cannot see every point). Metrics (metrics.json): held-out
PSNR of the torch march (the shader's twin) with the grid, per view and overall; the largest
difference per pixel the grid makes on the first held-out view (vs evaluating every sample); bytes,
seconds; with ``--preview`` the same held-out views drawn by the shader and their PSNR; and with
``baseline_steps`` > 0 the MLP-only network (NeRF frequency encoding + MLP) of the same bytes,
trained by the same loop on the same rays and measured the same way.
"""
from __future__ import annotations

import json
import math
import time

import numpy as np
import torch

from inshade.files import atomic_write
from inshade.metrics import psnr
from inshade.models.graph import GraphModule
from inshade.provenance import recorded_at
from inshade.scene.builder import (display_modes, network, reference, requires, scene_json, text_label,
                                    texture)

from . import radiance_field as rf
from . import radiance_field_march as march
from . import radiance_field_scene as scene
from .network import HashGridError, network_bytes, optimizer
from .radiance_field_render import (KIND, PREFIX_FIELD, PREFIX_OCCUPANCY, PROGRAM, REFERENCE_UNIFORM, SETTINGS,
                                    STOP, MarchSettings)

LN_STOP = -math.log(STOP)   # optical depth where the transmittance falls under STOP
BACKGROUND = (0.9, 0.9, 0.92)
SIGMA_SCALE = 1.0           # the density output is the extinction per box unit
GRID_DECAY = 0.95
FINAL_PROBES = 4            # lattice points per cell axis for the shipped occupancy grid
PROBE_CHUNK = 16            # samples per ray in the first block of the density-only pass
EMPTY_SAMPLES = 4096        # random points per step for the empty-space term
COMPARE_SIZE = 48           # pixels a side of the skip-vs-evaluate comparison
HELDOUT_FOLDER = "heldout"


def march_settings(s) -> MarchSettings:
    """The unit box, dt = 1 / samples_per_side (float32), enough steps for the box diagonal."""
    step = float(np.float32(1.0 / s.samples_per_side))
    return MarchSettings((0.0, 0.0, 0.0), 1.0, step, int(math.ceil(math.sqrt(3.0) / step)) + 1, BACKGROUND,
                         SIGMA_SCALE, int(s.occupancy_resolution))


def check(s) -> None:
    """Settings the run cannot use, refused before any work (the message names the option)."""
    for name, lo, hi in (("train_views", 1, 1000), ("heldout_views", 1, 100), ("train_size", 8, 1024),
                         ("heldout_size", 8, 1024), ("samples_per_side", 8, 4096), ("occupancy_resolution", 2, 512),
                         ("occupancy_every", 1, 10 ** 6), ("width", 4, 1024), ("depth", 1, 8)):
        v = getattr(s, name)
        if not lo <= v <= hi:
            raise HashGridError(f"--{name.replace('_', '-')}: must be in {lo}..{hi}, got {v}")
    if not 0.0 < s.occupancy_threshold < 1.0:
        raise HashGridError(f"--occupancy-threshold: must be in (0, 1) (optical thickness of a step), "
                            f"got {s.occupancy_threshold}")
    if s.empty_weight < 0:
        raise HashGridError(f"--empty-weight: must be >= 0, got {s.empty_weight}")
    rf.grid_shape(s)


# --- data ------------------------------------------------------------------------------------------

class Views:
    """Cameras (scene.json form), ground-truth images [V, H, W, 3] and their rays in box units."""

    def __init__(self, cameras: list[dict], size: int, m: MarchSettings):
        from inshade.scene.camera import camera_from_dict

        self.cameras, self.size = cameras, size
        self.images = np.stack([scene.render(c, size, size, m) for c in cameras])
        rays = [march.box_rays(camera_from_dict(c).uniforms(size, size), size, size, m) for c in cameras]
        self.ro = torch.cat([r[0] for r in rays])
        self.rd = torch.cat([r[1] for r in rays])
        self.rgb = torch.from_numpy(self.images.reshape(-1, 3).copy())


def make_data(s, m: MarchSettings):
    """(training Views, held-out Views)."""
    return (Views(scene.views(s.train_views, 0.0), s.train_size, m),
            Views(scene.views(s.heldout_views, 0.5), s.heldout_size, m))


# --- the loop --------------------------------------------------------------------------------------

def partial(graph: GraphModule, output: str):
    """x [P, 3] -> one output [P] of a graph with inputs x and d, evaluating only the nodes it needs
    (the density without the colour network)."""
    node = next(n for name, n, _ in graph.outputs if name == output)
    needed, todo = set(), [node]
    while todo:
        n = todo.pop()
        if n in graph.nodes and n not in needed:
            needed.add(n)
            todo += graph.wiring[n]

    def fn(x):
        values = {"x": x}
        for node_id, comp in graph.nodes.items():
            if node_id in needed:
                srcs = [values[w] for w in graph.wiring[node_id]]
                values[node_id] = comp(srcs[0] if len(srcs) == 1 else torch.cat(srcs, -1))
        return values[node].reshape(-1)
    return fn


class DensityGrid:
    """instant-NGP's density grid over G^3 cells (module docstring): starts full."""

    def __init__(self, m: MarchSettings, threshold: float, gen: torch.Generator):
        g = m.occupancy_resolution
        self.m, self.threshold, self.gen = m, threshold, gen
        self.sigma = torch.full((g, g, g), float("inf"))
        k, j, i = torch.meshgrid(*(torch.arange(g, dtype=torch.float32),) * 3, indexing="ij")
        self.corners = torch.stack([i, j, k], -1).reshape(-1, 3)

    def update(self, density_fn) -> None:
        g = self.m.occupancy_resolution
        x = (self.corners + torch.rand(self.corners.shape, generator=self.gen)) / g
        with torch.no_grad():
            sigma = torch.cat([density_fn(x[s:s + (1 << 17)]) for s in range(0, len(x), 1 << 17)])
        sigma = sigma.reshape(g, g, g) * self.m.sigma_scale
        self.sigma = torch.maximum(torch.where(torch.isinf(self.sigma), 0.0, self.sigma * GRID_DECAY), sigma)

    def occupied(self) -> torch.Tensor:
        thickness = self.sigma * self.m.step
        finite = torch.isfinite(thickness)
        level = min(self.threshold, float(thickness[finite].mean())) if finite.any() else self.threshold
        return rf.dilate(thickness > level)


def _kept(x, valid, density_fn, m: MarchSettings):
    """The valid samples before each ray's transmittance falls under STOP (density only, no
    gradients), evaluated in blocks that double along the ray."""
    scale_dt = m.sigma_scale * m.step
    depth = torch.zeros(len(x))
    sigma_dt = torch.zeros(valid.shape)
    k0, size = 0, PROBE_CHUNK
    with torch.no_grad():
        while k0 < valid.shape[1]:
            rows = (depth < LN_STOP).nonzero().squeeze(1)
            if not len(rows):
                break
            block = valid[rows, k0:k0 + size]
            if block.any():
                part = torch.zeros(block.shape)
                part[block] = density_fn(x[rows, k0:k0 + size][block]) * scale_dt
                sigma_dt[rows, k0:k0 + size] = part
                depth[rows] += part.sum(1)
            k0, size = k0 + size, 2 * size
    before = torch.cumsum(sigma_dt, 1) - sigma_dt
    return valid & (before < LN_STOP)


def _empty_space(density_fn, occupied, m: MarchSettings, gen) -> torch.Tensor:
    """Mean optical thickness of a step at random points of unoccupied cells."""
    x = torch.rand(EMPTY_SAMPLES, 3, generator=gen)
    c = march.cells_of(x, m.occupancy_resolution)
    x = x[~occupied[c[:, 2], c[:, 1], c[:, 0]]]
    if not len(x):
        return torch.zeros(())
    return torch.sum(density_fn(x)) * (m.sigma_scale * m.step) / EMPTY_SAMPLES


def fit(graph: GraphModule, train: Views, s, m: MarchSettings, lrs: dict, steps: int, desc: str) -> dict:
    """Train ``graph`` in place (module docstring); returns the training record."""
    from inshade.models.fit_loop import cosine, fit as fit_steps

    gen = torch.Generator().manual_seed(s.seed)
    density_fn = partial(graph, "density")
    grid = DensityGrid(m, s.occupancy_threshold, gen)
    opt = optimizer(graph, **lrs)
    bg = torch.tensor(m.background, dtype=torch.float32)
    state = {"per_ray": 32.0, "occupied": None}
    history, start = [], time.perf_counter()

    def step_loss(step):
        if step % s.occupancy_every == 0:
            grid.update(density_fn)
            state["occupied"] = grid.occupied()
        occupied = state["occupied"]
        rays = int(min(max(s.batch / state["per_ray"], 64), 1 << 14))
        pick = torch.randint(0, len(train.ro), (rays,), generator=gen)
        rd, target = train.rd[pick], train.rgb[pick]
        x, valid = march.candidates(train.ro[pick], rd, occupied, m)
        keep = _kept(x, valid, density_fn, m)
        width = max(int(keep.sum(1).max()), 1)
        x, keep = x[:, :width], keep[:, :width]
        r, k = keep.nonzero(as_tuple=True)
        out = graph(torch.cat([x[r, k], rd[r]], -1))
        sigma_dt = torch.zeros(keep.shape).index_put((r, k), out[:, 0] * (m.sigma_scale * m.step))
        rgb = torch.zeros(*keep.shape, 3).index_put((r, k), out[:, 1:4])
        loss = torch.mean((march.composite(sigma_dt, rgb, bg) - target) ** 2)
        photometric = float(loss.detach())
        if s.empty_weight > 0:
            loss = loss + s.empty_weight * _empty_space(density_fn, occupied, m, gen)
        return loss, photometric, rays, len(r)

    def after(step, returned, bar):
        _, photometric, rays, samples = returned
        state["per_ray"] = 0.9 * state["per_ray"] + 0.1 * max(samples / rays, 1.0)
        if step % 100 == 0 or step == steps - 1:
            history.append((step, round(-10 * math.log10(max(photometric, 1e-12)), 3)))
            bar.set_postfix(psnr=f"{history[-1][1]:.2f}", rays=rays)

    fit_steps(opt, step_loss, steps, lr_factor=cosine(steps), after_step=after, desc=desc)
    return {"steps": steps, "seconds": round(time.perf_counter() - start, 1), "psnr_batches": history,
            "occupied_fraction": round(float(grid.occupied().float().mean()), 4) if steps else 1.0}


def shipped_occupancy(graph: GraphModule, s, m: MarchSettings) -> torch.Tensor:
    """The bool [G, G, G] ([k, j, i]) grid shipped with the field (module docstring)."""
    sigma = rf.density_max(partial(graph, "density"), m.occupancy_resolution, FINAL_PROBES) * m.sigma_scale
    return rf.dilate(sigma * m.step > s.occupancy_threshold)


def measure(graph: GraphModule, occupancy: torch.Tensor, heldout: Views, m: MarchSettings) -> dict:
    """Held-out PSNR of the torch march with the grid (per view and over all), the images, and on the
    first view at COMPARE_SIZE the largest difference the grid makes (vs every sample evaluated)."""
    from inshade.scene.camera import camera_from_dict

    field = march.graph_field(graph)
    images, evals = [], []
    for cam in heldout.cameras:
        img, n = march.render(field, occupancy, camera_from_dict(cam).uniforms(heldout.size, heldout.size),
                              heldout.size, heldout.size, m)
        images.append(img)
        evals.append(float(n.mean()))
    cam = camera_from_dict(heldout.cameras[0]).uniforms(COMPARE_SIZE, COMPARE_SIZE)
    skip, n_skip = march.render(field, occupancy, cam, COMPARE_SIZE, COMPARE_SIZE, m)
    dense, n_dense = march.render(field, None, cam, COMPARE_SIZE, COMPARE_SIZE, m)
    return {**heldout_psnr(images, heldout.images), "evaluations_per_pixel": round(float(np.mean(evals)), 2),
            "skip_vs_evaluate": {"size": COMPARE_SIZE, "max_abs": round(float(np.abs(skip - dense).max()), 6),
                                 "evaluations_skip": round(float(n_skip.mean()), 2),
                                 "evaluations_evaluate": round(float(n_dense.mean()), 2)},
            "images": images}


def heldout_psnr(images, truth) -> dict:
    """PSNR (linear RGB, peak 1) per view and of all views' pixels together."""
    mse = float(np.mean([np.mean((np.asarray(a, np.float64) - b) ** 2) for a, b in zip(images, truth)]))
    return {"heldout_psnr": round(-10 * math.log10(mse), 3),
            "heldout_psnr_per_view": [round(float(psnr(a, b)), 3) for a, b in zip(images, truth)]}


# --- the asset -------------------------------------------------------------------------------------

def learning_rates(s, mlp_lr: float | None = None) -> dict:
    return dict(grid_lr=s.grid_lr, mlp_lr=s.mlp_lr if mlp_lr is None else mlp_lr, grid_eps=s.grid_eps,
                mlp_eps=s.mlp_eps, mlp_l2=s.mlp_l2)


def heldout_image(k: int, suffix: str = "exr") -> str:
    return f"{HELDOUT_FOLDER}/view_{k:02d}.{suffix}"


def scene_dict(name: str, title: str, heldout: Views) -> dict:
    """scene.json: the pass, both networks, the first held-out camera with its ground truth as the
    pass's reference texture (views reference / split / error; 8-bit sRGB) and as the scene's
    reference (display modes; linear EXR, the exact values)."""
    return scene_json(
        name, title, PROGRAM, (heldout.size, heldout.size),
        networks=[network(".", PREFIX_FIELD), network("occupancy", PREFIX_OCCUPANCY)],
        reference=reference(heldout_image(0), "linear", "screen"),
        textures=[texture(REFERENCE_UNIFORM, heldout_image(0, "png"), mipmaps=False, repeat=False)],
        camera=heldout.cameras[0],
        bookmarks={"held-out 0": heldout.cameras[0], "front": scene.orbit_camera(0.0, -15.0),
                   "top": scene.orbit_camera(30.0, -75.0)},
        display=display_modes("final", "reference", "error", "split"),
        labels=[text_label("held-out truth", (0.25, 0.95), {"view": "split"}),
                text_label("hash grid", (0.75, 0.95), {"view": "split"})],
        settings=json.loads(json.dumps(SETTINGS)),
        requires=requires(),
        notes="the reference is the ground truth of held-out view 0 (the scene's camera): views reference, "
              "split and error compare the shader's march with it there; view samples shows network "
              "evaluations per pixel / 64; empty_space evaluate marches without the occupancy grid",
    )


def write_views(out, heldout: Views, scene_name: str, metrics: dict) -> None:
    """The held-out ground truth (EXR per view, view 0 also as the pass's PNG), their cameras and
    scene.json."""
    from inshade.scene.image_io import write_exr, write_png

    for k, img in enumerate(heldout.images):
        write_exr(out / heldout_image(k), img)
    write_png(out / heldout_image(0, "png"), heldout.images[0])
    atomic_write(out / HELDOUT_FOLDER / "cameras.json", json.dumps(heldout.cameras, indent=1) + "\n")
    title = (f"Hash grid radiance field: {scene_name}, {metrics['bytes'] / 1024:.0f} KiB, held-out "
             f"{metrics['heldout_psnr']:.1f} dB")
    atomic_write(out / "scene.json", json.dumps(scene_dict(out.name, title, heldout), indent=1) + "\n")


def shader_psnr(out, heldout: Views) -> dict:
    """The held-out views drawn by the shader from the written asset, and their PSNR."""
    from inshade.runtime.headless import render_scene
    from inshade.scene.description import load_scene

    drawn = [render_scene(load_scene(out), width=heldout.size, height=heldout.size, camera=c)
             for c in heldout.cameras]
    return {**heldout_psnr([image[..., :3] for image, _ in drawn], heldout.images),
            "gl_renderer": drawn[0][1]["gl"]["renderer"]}


def train_baseline(s, train: Views, heldout: Views, m: MarchSettings, budget: int) -> dict:
    """The MLP-only network of ``budget`` bytes, trained by the same loop, measured the same way."""
    g = rf.baseline_graph(s.n_freqs, s.baseline_depth, s.width, s.depth, budget, s.seed)
    log = fit(g, train, s, m, learning_rates(s, s.baseline_lr), s.baseline_steps, "mlp baseline")
    shipped = GraphModule.from_bundle(g.export(KIND, "baseline"))
    result = measure(shipped, shipped_occupancy(shipped, s, m), heldout, m)
    widths = [n.linear.out_features for n in g.nodes.values() if n.type == "dense"]
    return {**{k: v for k, v in result.items() if k != "images"}, "bytes": network_bytes(g),
            "network": f"frequency({s.n_freqs}) -> " + " -> ".join(f"dense {w}" for w in widths),
            "steps": s.baseline_steps, "lr": s.baseline_lr, "train_seconds": log["seconds"],
            "psnr_batches": log["psnr_batches"]}


def train(run) -> int:
    """Render the views, fit, build the occupancy grid, measure, write the asset folder."""
    from .image import save_fp16
    from inshade.scene.image_io import write_png

    s = run.settings
    torch.manual_seed(s.seed)
    m = march_settings(s)
    t0 = time.perf_counter()
    train_views, heldout = make_data(s, m)
    data_seconds = time.perf_counter() - t0
    shape = rf.grid_shape(s)
    g = rf.field_graph(shape, s.width, s.depth, s.seed)
    log = fit(g, train_views, s, m, learning_rates(s), s.steps, "hash_grid radiance field")
    provenance = {
        "command": run.command, "preset": run.preset, "settings": run.record()["settings"],
        "data": f"procedural scene {s.scene!r} (radiance_field_scene.py): {s.train_views} training views at "
                f"{s.train_size}^2, {s.heldout_views} held-out at {s.heldout_size}^2, rendered by its analytic march",
        "training": "occupancy-guided samples of the march, MSE on composited pixels + empty-space term, Adam "
                    "(instant-NGP's split), cosine decay to 5%",
        "device": str(run.device), "torch": torch.__version__,
        **recorded_at(),
    }
    bundle = g.export(KIND, run.out.name, provenance=provenance, render=m.to_render())
    shipped = GraphModule.from_bundle(bundle)        # fp16 tables as exported: what the shader reads
    occupancy = shipped_occupancy(shipped, s, m)
    result = measure(shipped, occupancy, heldout, m)
    images = result.pop("images")
    metrics = {**result, "bytes": network_bytes(g), "occupancy_bytes": int(occupancy.numel()),
               "occupied_fraction": round(float(occupancy.float().mean()), 4),
               "encoding": {"levels": shape.levels, "features": shape.features,
                            "log2_table_size": shape.log2_table_size, "base_resolution": shape.base_resolution,
                            "per_level_scale": shape.per_level_scale, "finest_resolution": shape.finest_resolution(),
                            "table_rows": shape.rows(), "table_bytes_fp16": shape.table_bytes()},
               "train_seconds": log["seconds"], "data_seconds": round(data_seconds, 1),
               "occupied_fraction_training": log["occupied_fraction"], "psnr_batches": log["psnr_batches"],
               "train_threads": torch.get_num_threads(), "device": str(run.device)}
    if s.baseline_steps > 0:
        metrics["mlp_baseline"] = train_baseline(s, train_views, heldout, m, metrics["bytes"])
    bundle.meta["metrics"] = {k: v for k, v in metrics.items() if k not in ("psnr_batches", "mlp_baseline")}
    save_fp16(bundle, run.out)
    rf.occupancy_bundle(occupancy, {"grid": f"{m.occupancy_resolution}^3 cells: the field's density max over "
                                            f"{FINAL_PROBES}^3 points per cell, x dt > {s.occupancy_threshold:g}, "
                                            "grown by one cell"}).save(run.out / "occupancy")
    write_views(run.out, heldout, s.scene, metrics)
    write_png(run.out / "preview.png", images[0])
    if run.args.preview:
        metrics["shader"] = shader_psnr(run.out, heldout)
    run.write_metrics(metrics)
    base = metrics.get("mlp_baseline")
    print(f"wrote {run.out}: held-out PSNR {metrics['heldout_psnr']:.2f} dB (torch march)"
          + (f", {metrics['shader']['heldout_psnr']:.2f} dB (shader)" if "shader" in metrics else "")
          + f", {metrics['bytes']} bytes, {metrics['train_seconds']:.0f} s"
          + (f"; MLP-only at {base['bytes']} bytes: {base['heldout_psnr']:.2f} dB" if base else ""))
    return 0
