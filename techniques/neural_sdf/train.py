"""Neural SDF: an MLP fitted to a watertight mesh, sphere traced in-shader with a safe step.

The paper's weight-encoded STANFORD-BUNNY (Learnt Transfer, Dhawal et al. 2022 §3.2): an MLP q -> distance,
q = (p - center) / radius in the unit ball of the mesh's bound, exported as
a network SDF (models/network_sdf.py contract) and sphere traced in-shader by lib/sdf.

Data: area-weighted surface samples (trimesh, seeded) pushed off the surface by Gaussian offsets
(two scales, ``SIGMAS`` x radius) plus uniform samples in the bound's cube; exact signed distances
from the mesh by point-cloud-utils (libigl, C++; ~20k points/s on one shared core, where trimesh's
``closest_point`` does ~250/s), with trimesh (``closest_point`` + embree ``contains``) as the slow
fallback. The mesh must be watertight (inshade.mesh.load_mesh(require_watertight=True)).

Safe step. Sphere tracing advances by ``d * step_scale`` and never overshoots the surface if
``step_scale <= 1/L``, L the network's Lipschitz constant in world units (radius cancels: input
and output are scaled by it). ``lipschitz_bound`` gives an upper bound from the weights: the
product over the chain of each dense layer's spectral norm, each activation's constant
(relu/softplus/tanh 1, sigmoid 1/4, leaky_relu max(1, |slope|), sin omega0) and the frequency
encoding's exact constant sqrt([x kept] + sum_k (2^k pi)^2). Unconstrained fits reach bounds of
~20-30 (true max |grad| ~1.3), which would need ~1000 steps per ray; so training adds
``lipschitz_weight * relu(log L - log lipschitz_target)`` to the L1 loss (spectral norms are
differentiable) and the exported ``trace.step_scale = min(0.9, 1/L)`` is a guarantee, not a
guess. The price is detail: on the procedural rabbit (32x3, 3000 steps) target 1.5 gives a
Chamfer distance of 0.022 r and IoU 0.88, target 4 (default: step_scale 0.25) 0.014 r and
0.91, no penalty (bound ~30, unsafe steps) 0.015 r after 400 steps; thin parts (the ears) need
a larger target or network.
The bound sphere (mesh's, grown by 8%) and ``max_steps`` (trace_settings) cap every ray.

Activation: ``softplus`` trains as softplus(100 x) / 100 (``SmoothReLU``: SAL's geometric
initialisation works as for relu, shading normals are smooth) and is exported with the 100s
folded into the weights (``fold_beta``), so codegen sees a plain softplus MLP.

Metrics (held out, world units and relative to the radius): mean |network| on surface samples,
mean |d error| on near-surface and uniform samples, inside/outside IoU on uniform samples, and a
symmetric Chamfer distance between marching cubes of the network (64^3) and the mesh.

Command: ``inshade train neural_sdf --mesh PATH --out DIR [--preset quick|ship] [--width 32 --layers 3
--steps 3000] [--device auto|cpu|cuda[:N]]`` (the fit runs on the device; the signed distances come from the
mesh on the CPU, and evaluation and export run on the CPU). ``--preset ship`` (the default) is what built
the shipped network SDF (trained/prt_neural_bunny/sdf) from the default mesh; OUT/metrics.json records
the preset and the resolved settings.
Without ``--mesh``, the procedural rabbit
(inshade.mesh.bunny) is generated into /tmp/inshade_mesh/bunny.ply first.
"""
from __future__ import annotations

import argparse
import datetime
import json
import math
import shlex
import sys
import time
from pathlib import Path

import numpy as np
import torch

from inshade import asset_folder, command
from inshade.devices import DeviceError, add_device_argument, resolve_device
from inshade.files import atomic_write
from inshade.mesh import DEFAULT_OUT as DEFAULT_MESH, bounding_sphere, load_mesh
from inshade.sdf import f32

from inshade.models import activations as _act
from inshade.models import encodings as _enc
from inshade.models.graph import GraphModule
from inshade.models.network_sdf import NetworkSdfModule

KIND = "neural_sdf"
SIGMAS = (0.01, 0.05)            # Gaussian offsets off the surface, x radius
BOUND_MARGIN = 0.08              # the bound sphere is the mesh's grown by 8% (room for normals, offsets)
ACTIVATIONS = ("softplus", "relu", "leaky_relu", "tanh")
DEFAULTS = dict(out=None, mesh=None, width=32, layers=3, freqs=0, activation="softplus",
                steps=3000, batch=8192, lr=2e-3, samples=300_000, seed=0, lipschitz_target=4.0,
                lipschitz_weight=0.05, hit_eps=1e-3, threads=1)
# --preset: "ship" is what built the shipped network SDF (trained/prt_neural_bunny/sdf, on the
# procedural rabbit): 48 wide with two octaves of position encoding, the capacity that keeps thin
# parts apart (the rabbit's ears: a 32x3 plain MLP fused them; 48x3 + 2 octaves: 0.2% of the gap
# between them inside, was 21%; surface error 2.2e-3 r, was 6.8e-3 r); "quick" is a small fit for
# a smoke run (seconds).
PRESETS = {"ship": dict(steps=3000, samples=300_000, batch=8192, width=48, freqs=2),
           "quick": dict(steps=100, samples=10_000, batch=4096)}
SETTINGS = ("width", "layers", "freqs", "activation", "steps", "batch", "lr", "samples", "seed",
            "lipschitz_target", "lipschitz_weight")


def preset_settings(preset: str, asset: str | None = None) -> dict:
    """The settings ``--preset PRESET`` resolves to with no other option (one recipe: ``asset`` is ignored)."""
    return {k: PRESETS[preset].get(k, DEFAULTS[k]) for k in SETTINGS}


# ---------------------------------------------------------------------------------------------
# data

def signed_distance(mesh, points: np.ndarray) -> np.ndarray:
    """Exact signed distance (negative inside) of points [N, 3] to a watertight mesh, float64."""
    points = np.ascontiguousarray(points, np.float64)
    try:
        import point_cloud_utils as pcu
    except ImportError:
        import trimesh

        _, dist, _ = trimesh.proximity.closest_point(mesh, points)
        return np.where(mesh.contains(points), -dist, dist)
    sd, _, _ = pcu.signed_distance_to_mesh(points, np.ascontiguousarray(mesh.vertices, np.float64),
                                           np.ascontiguousarray(mesh.faces, np.int64))
    return np.asarray(sd, np.float64)


def sample_points(mesh, center, radius: float, n: int, seed: int = 0, progress: bool = False) -> dict:
    """{"surface": [n/4, 3] points on the mesh, "near": [n/2, 3] Gaussian-offset points and
    "uniform": [n/4, 3] points in the bound's cube, each with "<name>_sdf"} (world units)."""
    import trimesh

    from inshade.progress import progress as progress_bar

    rng = np.random.default_rng(seed)
    n_s, n_n = n // 4, n // 2
    n_u = n - n_s - n_n
    surface, _ = trimesh.sample.sample_surface(mesh, n_s + n_n, seed=seed)
    sig = np.repeat(np.asarray(SIGMAS) * radius, (n_n + 1) // 2)[:n_n]
    near = surface[n_s:] + rng.normal(size=(n_n, 3)) * sig[:, None]
    uniform = np.asarray(center) + rng.uniform(-radius, radius, (n_u, 3))
    out = {"surface": surface[:n_s], "near": near, "uniform": uniform}
    for name in ("near", "uniform"):
        pts = out[name]
        chunks = np.array_split(np.arange(len(pts)), max(1, len(pts) // 20000))
        sd = [signed_distance(mesh, pts[c]) for c in progress_bar(chunks, desc=f"sdf {name}", enabled=progress)]
        out[name + "_sdf"] = np.concatenate(sd)
    out["surface_sdf"] = np.zeros(n_s)
    return out


# ---------------------------------------------------------------------------------------------
# model and its Lipschitz bound

class SmoothReLU(_act.Softplus):
    """Training-time activation softplus(beta x) / beta: 1-Lipschitz and ~relu (within
    log(2) / beta), so the SAL geometric initialisation holds, but smooth (shaded normals
    without facets). Not exported as such: ``fold_beta`` turns the graph into plain softplus."""

    def __init__(self, beta: float = 100.0):
        super().__init__()
        self.beta = float(beta)

    def forward(self, x):
        z = x * self.beta
        return (torch.clamp_min(z, 0) + torch.log1p(torch.exp(-z.abs()))) * (1.0 / self.beta)


def build(width: int = 32, layers: int = 3, freqs: int = 0, activation: str = "softplus",
          beta: float = 100.0) -> GraphModule:
    """q[3] -> [frequency(freqs)] -> (dense width -> activation) * layers -> dense 1, with the
    geometric initialisation of SAL (Atzmon & Lipman 2020): the net starts as |q| - 0.5, a sphere
    (without it, an L1 fit from a default init collapses to the median, ~0 everywhere).
    ``softplus`` trains with ``SmoothReLU(beta)``; export through ``fold_beta``."""
    if activation not in ACTIVATIONS:
        raise ValueError(f"unknown activation {activation!r} (choose from {', '.join(ACTIVATIONS)})")
    g = GraphModule([("position", 3, "position")])
    src = "position"
    if freqs:
        src = g.add("enc", _enc.Frequency(freqs, include_input=True), src)
    for i in range(layers):
        src = g.dense(f"l{i}", src, width)
        act = {"softplus": lambda: SmoothReLU(beta), "relu": _act.ReLU, "leaky_relu": _act.LeakyReLU,
               "tanh": _act.Tanh}[activation]
        src = g.add(f"a{i}", act(), src)
    src = g.dense(f"l{layers}", src, 1)
    g.output("distance", src, "sdf")
    if activation != "tanh":
        _geometric_init(g, layers, width)
    return g


def _geometric_init(g: GraphModule, layers: int, width: int) -> None:
    with torch.no_grad():
        for i in range(layers):
            lin = g.nodes[f"l{i}"].linear
            torch.nn.init.normal_(lin.weight, 0.0, math.sqrt(2.0) / math.sqrt(width))
            torch.nn.init.zeros_(lin.bias)
        last = g.nodes[f"l{layers}"].linear
        torch.nn.init.normal_(last.weight, math.sqrt(math.pi) / math.sqrt(width), 1e-4)
        torch.nn.init.constant_(last.bias, -0.5)


def fold_beta(graph: GraphModule) -> GraphModule:
    """The same function with plain softplus (what codegen emits): softplus(beta z) / beta per
    hidden layer, the betas folded into the weights. First layer (W, b) -> (beta W, beta b);
    later hidden layers (W, b) -> (W, beta b) (their input is already beta times larger); the output
    layer W -> W / beta. The spectral-norm product, hence the Lipschitz bound, is unchanged.
    Graphs without SmoothReLU come back as an exact copy."""
    out = GraphModule([(n, d, s) for n, d, s in graph.inputs])
    pending = 1.0           # the factor the current activations carry (beta after a SmoothReLU)
    for node_id, comp in graph.nodes.items():
        inputs = graph.wiring[node_id]
        if isinstance(comp, SmoothReLU):
            out.add(node_id, _act.Softplus(), inputs)
            pending = comp.beta
            continue
        if comp.type == "dense":
            nxt = _next_activation(graph, node_id)
            beta = nxt.beta if isinstance(nxt, SmoothReLU) else 1.0
            new = out.dense(node_id, inputs, comp.linear.out_features, comp.linear.bias is not None)
            with torch.no_grad():
                # input scaled by `pending`, output wanted scaled by `beta`
                new_lin = out.nodes[new].linear
                new_lin.weight.copy_(comp.linear.weight * (beta / pending))
                if comp.linear.bias is not None:
                    new_lin.bias.copy_(comp.linear.bias * beta)
            pending = 1.0 if beta == 1.0 else pending
            continue
        out.add(node_id, type(comp)(**comp.params()), inputs)
    for name, node, sem in graph.outputs:
        out.output(name, node, sem)
    return out


def _next_activation(graph: GraphModule, node_id: str):
    ids = list(graph.nodes)
    i = ids.index(node_id)
    if i + 1 < len(ids) and graph.wiring[ids[i + 1]] == [node_id]:
        return graph.nodes[ids[i + 1]]
    return None


def _activation_lipschitz(comp) -> float:
    t = comp.type
    if t in ("relu", "softplus", "tanh", "identity"):
        return 1.0
    if t == "sigmoid":
        return 0.25
    if t == "leaky_relu":
        return max(1.0, abs(comp.slope))
    if t == "sin":
        return abs(comp.omega0)
    if t == "frequency":
        s = sum(((2.0 ** k) * math.pi) ** 2 for k in range(comp.n_freqs))
        return math.sqrt(s + (1.0 if comp.include_input else 0.0))
    return math.inf


def lipschitz_bound(graph: GraphModule, differentiable: bool = False):
    """Upper bound on the Lipschitz constant (L2 -> L2) of a chain graph: product of the dense
    layers' spectral norms and the other components' constants (inf for what has no bound here,
    e.g. exp, lookup arrays, or a graph that is not a chain). A tensor if ``differentiable``."""
    total = torch.ones(()) if differentiable else 1.0
    prev = [graph.inputs[0][0]] if len(graph.inputs) == 1 else None
    for node_id, comp in graph.nodes.items():
        if prev is None or graph.wiring[node_id] != prev:
            return math.inf
        if comp.type == "dense":
            s = torch.linalg.matrix_norm(comp.linear.weight, ord=2)
            total = total * (s if differentiable else float(s.detach()))
        else:
            total = total * _activation_lipschitz(comp)
        prev = [node_id]
    return total


def trace_settings(lipschitz: float, radius: float, hit_eps: float) -> dict:
    """``render.sdf.trace`` from the bound: step_scale = min(0.9, 1 / L); max_steps enough for
    ~2 bound diameters of free-space stepping at typical distances (~0.1 radius) plus the slow
    approach to the surface, capped at 512."""
    step = min(0.9, 1.0 / lipschitz) if math.isfinite(lipschitz) and lipschitz > 0 else 0.1
    steps = int(min(512, max(64, math.ceil(48 / step))))
    return {"max_steps": steps, "step_scale": f32(step), "hit_eps": f32(hit_eps * radius),
            "normal_eps": f32(hit_eps * radius)}


# ---------------------------------------------------------------------------------------------
# training and evaluation

def fit(graph: GraphModule, data: dict, center, radius: float, *, steps: int, batch: int, lr: float, seed: int,
        lipschitz_target: float, lipschitz_weight: float, progress: bool | None = None) -> dict:
    """Adam on the L1 error of the normalised distance (surface, near and uniform samples
    mixed), cosine-decayed lr, plus the Lipschitz penalty. Runs on the graph's device (batch
    indices drawn on a CPU generator, then moved). Deterministic for a seed and device."""
    from inshade.progress import progress as progress_bar

    device = next(graph.parameters()).device
    c = np.asarray(center, np.float64)
    inv_r = 1.0 / radius
    parts = ("surface", "near", "uniform")
    x = torch.from_numpy(np.concatenate([(data[k] - c) * inv_r for k in parts]).astype(np.float32)).to(device)
    y = torch.from_numpy(np.concatenate([data[k + "_sdf"] * inv_r for k in parts]).astype(np.float32)).to(device)
    opt = torch.optim.Adam(graph.parameters(), lr=lr)
    sched = torch.optim.lr_scheduler.LambdaLR(
        opt, lambda s: 0.02 + 0.98 * 0.5 * (1 + math.cos(math.pi * min(s / max(steps, 1), 1.0))))
    gen = torch.Generator().manual_seed(seed)
    log_target = math.log(lipschitz_target)
    losses, start = [], time.perf_counter()
    bar = progress_bar(range(steps), desc="neural_sdf", enabled=progress)
    for step in bar:
        idx = torch.randint(0, x.shape[0], (batch,), generator=gen).to(device)
        err = (graph(x[idx])[:, 0] - y[idx]).abs().mean()
        loss = err
        if lipschitz_weight > 0:
            lip = lipschitz_bound(graph, differentiable=True)
            loss = loss + lipschitz_weight * torch.relu(torch.log(lip) - log_target)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        sched.step()
        if step % 100 == 0 or step == steps - 1:
            losses.append((step, float(err.detach())))
            bar.set_postfix(l1=f"{float(err.detach()):.2e}", L=f"{lipschitz_bound(graph):.2f}")
    return {"seconds": time.perf_counter() - start, "losses": losses}


def evaluate(module: NetworkSdfModule, mesh, data: dict, radius: float, mc_resolution: int = 64) -> dict:
    """Held-out quality numbers (world units; ``*_rel`` divided by the radius)."""
    out = {}
    with torch.no_grad():
        pred = {k: module(torch.from_numpy(data[k].astype(np.float32))).double().numpy()
                for k in ("surface", "near", "uniform")}
    out["surface_abs_mean"] = float(np.abs(pred["surface"]).mean())
    out["near_abs_err_mean"] = float(np.abs(pred["near"] - data["near_sdf"]).mean())
    out["uniform_abs_err_mean"] = float(np.abs(pred["uniform"] - data["uniform_sdf"]).mean())
    inside_t, inside_p = data["uniform_sdf"] < 0, pred["uniform"] < 0
    out["iou_uniform"] = float((inside_t & inside_p).sum() / max(1, (inside_t | inside_p).sum()))
    out.update({k + "_rel": v / radius for k, v in list(out.items()) if k != "iou_uniform"})
    out.update(_chamfer(module, mesh, radius, mc_resolution))
    # empirical Lipschitz: max |grad| over the held-out samples (a lower bound on L)
    p = torch.from_numpy(np.concatenate([data["near"], data["uniform"]]).astype(np.float32)).requires_grad_(True)
    (g,) = torch.autograd.grad(module(p).sum(), p)
    out["grad_norm_max"] = float(g.norm(dim=1).max())
    out["grad_norm_mean_near"] = float(g[: len(data["near"])].norm(dim=1).mean())
    return out


def _chamfer(module: NetworkSdfModule, mesh, radius: float, res: int) -> dict:
    """Symmetric Chamfer (mean nearest-neighbour distance both ways, /2) between 20k samples of
    the network's marching-cubes surface and 20k samples of the mesh."""
    import trimesh
    from scipy.spatial import cKDTree
    from skimage.measure import marching_cubes

    c = np.asarray(module.scene.center, np.float64)
    axis = np.linspace(-radius, radius, res)
    grid = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), -1).reshape(-1, 3) + c
    with torch.no_grad():
        field = module(torch.from_numpy(grid.astype(np.float32))).numpy().reshape(res, res, res)
    if not (field.min() < 0 < field.max()):
        return {"chamfer": math.inf, "chamfer_rel": math.inf}
    v, f, _, _ = marching_cubes(field, 0.0, spacing=(axis[1] - axis[0],) * 3)
    net_mesh = trimesh.Trimesh(v - radius + c, f, process=False)
    a, _ = trimesh.sample.sample_surface(net_mesh, 20000, seed=1)
    b, _ = trimesh.sample.sample_surface(mesh, 20000, seed=2)
    ch = 0.5 * (cKDTree(b).query(a)[0].mean() + cKDTree(a).query(b)[0].mean())
    return {"chamfer": float(ch), "chamfer_rel": float(ch / radius)}


def default_name(mesh) -> str:
    """The asset folder's name when no --out is given: neural_sdf_<mesh file stem>."""
    return f"{KIND}_{Path(mesh).stem if mesh else DEFAULT_MESH.stem}"


def train(*, out=DEFAULTS["out"], mesh=None, width=DEFAULTS["width"], layers=DEFAULTS["layers"],
          freqs=DEFAULTS["freqs"], activation=DEFAULTS["activation"], steps=DEFAULTS["steps"],
          batch=DEFAULTS["batch"], lr=DEFAULTS["lr"], samples=DEFAULTS["samples"], seed=DEFAULTS["seed"],
          lipschitz_target=DEFAULTS["lipschitz_target"], lipschitz_weight=DEFAULTS["lipschitz_weight"],
          hit_eps=DEFAULTS["hit_eps"], albedo=(0.8, 0.8, 0.8), command: str | None = None,
          progress: bool | None = None, mc_resolution: int = 64, threads: int | None = DEFAULTS["threads"],
          preview: bool = False, device="cpu", preset: str | None = None):
    """Fit (on ``device``, a torch.device or its name), evaluate and write the bundle into ``out``
    (+ metrics in it). Returns the Bundle.
    ``threads``: torch intra-op threads while fitting (1 by default: on a shared 2-core machine two
    spinning threads made each step ~15x slower than one; None leaves torch's setting)."""
    previous = torch.get_num_threads()
    if threads:
        torch.set_num_threads(int(threads))
    try:
        return _train(out, mesh, width, layers, freqs, activation, steps, batch, lr, samples, seed,
                      lipschitz_target, lipschitz_weight, hit_eps, albedo, command, progress, mc_resolution, preview,
                      torch.device(device), preset)
    finally:
        torch.set_num_threads(previous)


def _train(out, mesh, width, layers, freqs, activation, steps, batch, lr, samples, seed, lipschitz_target,
           lipschitz_weight, hit_eps, albedo, command, progress, mc_resolution, preview, device, preset):
    torch.manual_seed(seed)
    if mesh is None:
        from inshade.mesh import write_bunny

        mesh = DEFAULT_MESH if DEFAULT_MESH.is_file() else write_bunny(DEFAULT_MESH)
    mesh_path = Path(mesh)
    tri = load_mesh(mesh_path, require_watertight=True)
    center, radius = bounding_sphere(tri, BOUND_MARGIN)
    center, radius = tuple(f32(c) for c in center), f32(radius)
    t0 = time.perf_counter()
    data = sample_points(tri, center, radius, samples, seed, progress)
    held = sample_points(tri, center, radius, max(4000, samples // 10), seed + 1, progress)
    data_seconds = time.perf_counter() - t0
    # initialised on the CPU generator, then moved: the same start on every device
    graph = build(width, layers, freqs, activation).to(device)
    log = fit(graph, data, center, radius, steps=steps, batch=batch, lr=lr, seed=seed,
              lipschitz_target=lipschitz_target, lipschitz_weight=lipschitz_weight, progress=progress)
    graph = fold_beta(graph.cpu())     # evaluation and export on the CPU
    lip = float(lipschitz_bound(graph))
    module = NetworkSdfModule(graph, trace_settings(lip, radius, hit_eps), center, radius, albedo, KIND)
    t1 = time.perf_counter()
    metrics = evaluate(module, tri, held, radius, mc_resolution)
    metrics.update({
        "lipschitz_bound": lip, "step_scale": module.scene.trace["step_scale"],
        "params": int(sum(p.numel() for p in graph.parameters())),
        "data_seconds": round(data_seconds, 2), "train_seconds": round(log["seconds"], 2),
        "eval_seconds": round(time.perf_counter() - t1, 2),
        "samples_per_second_sdf": round(1.1 * samples / max(data_seconds, 1e-9)),
        "final_l1_normalised": log["losses"][-1][1] if log["losses"] else None,
        "device": str(device),
    })
    kw = dict(out=out, mesh=mesh_path, width=width, layers=layers, freqs=freqs, activation=activation,
              steps=steps, batch=batch, lr=lr, samples=samples, seed=seed, lipschitz_target=lipschitz_target,
              lipschitz_weight=lipschitz_weight)
    provenance = {
        "command": command or shlex.join(["inshade", "train", "neural_sdf"] + [
            s for k, v in kw.items() for s in (f"--{k.replace('_', '-')}", str(v))]),
        "mesh": str(mesh_path), "mesh_faces": int(len(tri.faces)), "mesh_vertices": int(len(tri.vertices)),
        "sampling": f"{samples}: 1/4 on the surface, 1/2 surface + N(0, ({SIGMAS[0]}r, {SIGMAS[1]}r)), "
                    f"1/4 uniform in the bound's cube; exact signed distance (point-cloud-utils)",
        "loss": "L1 on distance / radius + lipschitz_weight * relu(log L - log target)",
        "optimizer": "adam, cosine decay to 2%", **{k: v for k, v in kw.items() if k not in ("out", "mesh")},
        "preset": preset,
        "device": str(device),
        "torch": torch.__version__,
        "date_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
    }
    bundle = module.export(KIND, KIND, provenance=provenance, metrics=metrics)
    out = Path(out) if out else asset_folder.default(default_name(mesh))
    bundle.save(out)
    # metrics.json: the bundle's metrics plus the preset and the settings it resolved to
    settings = {k: kw[k] for k in SETTINGS}
    atomic_write(Path(out) / "metrics.json", json.dumps({"command": provenance["command"], "preset": preset,
                                                         "settings": settings, **metrics}, indent=1) + "\n")
    if preview:
        from inshade.runtime.image_io import write_png

        image, info = render_preview(bundle)
        write_png(Path(out) / "preview.png", image)
        print(f"preview.png: {info['seconds']:.2f} s on {info['gl_renderer']}", file=sys.stderr)
    return bundle


def render_preview(bundle, size: int = 256, sky: str = "sunset", yaw: float = 35.0, pitch: float = 15.0,
                   ctx=None) -> tuple[np.ndarray, dict]:
    """The bundle through the real shader path (lib/sdf + passes/sdf_diffuse, network SDF chunk):
    linear RGB [size, size, 3] (image orientation) and {"gl_renderer", "seconds"} (first draw
    includes the driver's compile). Orbit camera framing the bound sphere."""
    from inshade.codegen.network_sdf import NetworkSdfScene, network_sdf_chunks
    from inshade.codegen.sdf import environment_sh
    from inshade.codegen.spherical_harmonics import sh_chunks
    from inshade.runtime.camera import OrbitCamera
    from inshade.runtime.context import shared_context
    from inshade.runtime.network import NetworkResources
    from inshade.runtime.programs import ProgramCache
    from inshade.runtime.render import FullscreenPass, float_target, read_rgba, release_target

    ctx = ctx or shared_context()
    scene = NetworkSdfScene.from_bundle(bundle)
    chunks, gen = network_sdf_chunks(bundle)
    cam = OrbitCamera(target=scene.center, distance=scene.radius / math.sin(math.radians(22.5)), yaw=yaw, pitch=pitch)
    prog = ProgramCache(ctx).get("common/fullscreen.vert", "passes/sdf_diffuse.frag", chunks={**chunks, **sh_chunks(4)})
    res = NetworkResources(ctx, gen)
    fbo = float_target(ctx, size, size)
    pass_ = FullscreenPass(ctx, prog)
    try:
        res.bind(prog)
        t = time.perf_counter()
        pass_.render(fbo, uniforms={**cam.uniforms(size, size), "u_size": (float(size), float(size)),
                                    "u_sh": environment_sh(sky, 0.0).tobytes()})
        image = read_rgba(fbo)[..., :3]
        seconds = time.perf_counter() - t
    finally:
        pass_.vao.release()
        res.release()
        release_target(fbo)
        prog.release()
    return image, {"gl_renderer": ctx.info["GL_RENDERER"], "seconds": seconds, "camera": cam.to_dict()}


# ---------------------------------------------------------------------------------------------
# command line

def add_arguments(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    d = DEFAULTS
    parser.add_argument("--mesh", default=None,
                        help="watertight OBJ/PLY/GLB (default: the procedural rabbit, generated into "
                             f"{DEFAULT_MESH})")
    asset_folder.add_arguments(parser, "neural_sdf_<mesh>")
    parser.add_argument("--preset", default="ship", choices=sorted(PRESETS),
                        help="ship: what built the shipped network SDF (trained/prt_neural_bunny/sdf, with the "
                             "default mesh); quick: a small fit in seconds; options given explicitly override "
                             "the preset (default: %(default)s)")
    add_device_argument(parser)
    parser.add_argument("--width", type=int, help="hidden width (default: the preset's)")
    parser.add_argument("--layers", type=int, help="hidden layers (default: the preset's)")
    parser.add_argument("--freqs", type=int,
                        help="frequency-encoding octaves, 0 = plain MLP (default: the preset's)")
    parser.add_argument("--activation", default=d["activation"], choices=ACTIVATIONS, help="(default: %(default)s)")
    parser.add_argument("--steps", type=int, help="optimizer steps (default: the preset's)")
    parser.add_argument("--batch", type=int, help="points per step (default: the preset's)")
    parser.add_argument("--lr", type=float, default=d["lr"], help="Adam learning rate (default: %(default)s)")
    parser.add_argument("--samples", type=int, help="training points (default: the preset's)")
    parser.add_argument("--seed", type=int, default=d["seed"], help="random seed (default: %(default)s)")
    parser.add_argument("--lipschitz-target", type=float, default=d["lipschitz_target"],
                        help="the penalty starts above this bound (default: %(default)s)")
    parser.add_argument("--lipschitz-weight", type=float, default=d["lipschitz_weight"],
                        help="weight of the Lipschitz penalty, 0 = off (default: %(default)s)")
    parser.add_argument("--preview", action="store_true",
                        help="also render preview.png through the GLSL path (headless EGL)")
    parser.add_argument("--threads", type=int, default=d["threads"],
                        help="torch threads while fitting (default: %(default)s)")
    return parser


def run(args: argparse.Namespace) -> int:
    device = resolve_device(args.device)   # first: a CUDA the machine lacks fails before any work
    args.out = str(asset_folder.claim(args.out, default_name(args.mesh), force=args.force))
    kw = {k: getattr(args, k) for k in ("out", "mesh", "width", "layers", "freqs", "activation", "steps", "batch",
                                         "lr", "samples", "seed", "lipschitz_target", "lipschitz_weight", "threads",
                                         "preview")}
    for k in ("width", "layers", "freqs", *PRESETS[args.preset]):   # explicit option > the preset's > default
        if kw[k] is None:
            kw[k] = PRESETS[args.preset].get(k, DEFAULTS[k])
    if kw["steps"] < 0 or kw["width"] < 1 or kw["layers"] < 1 or kw["samples"] < 100:
        raise SystemExit("--steps must be >= 0, --width and --layers >= 1, --samples >= 100")
    bundle = train(**kw, device=device, preset=args.preset)
    m = bundle.meta["metrics"]
    print(f"wrote {bundle.path}: surface |d| {m['surface_abs_mean_rel']:.2e} r, IoU {m['iou_uniform']:.4f}, "
          f"Chamfer {m['chamfer_rel']:.2e} r, Lipschitz bound {m['lipschitz_bound']:.2f} -> step_scale "
          f"{m['step_scale']:.3f} ({m['params']} params; data {m['data_seconds']:.0f} s, "
          f"train {m['train_seconds']:.0f} s)")
    return 0


def main(argv=None) -> int:
    return command.main("inshade train neural_sdf", __doc__, add_arguments, run, argv, errors=(DeviceError,))

