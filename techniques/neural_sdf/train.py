"""Neural SDF: an MLP fitted to a watertight mesh, sphere traced in-shader with a safe step.

The paper's weight-encoded STANFORD-BUNNY (Learnt Transfer, Dhawal et al. 2022 §3.2): an MLP q -> distance,
q = (p - center) / radius in the unit ball of the mesh's bound, exported as
a network SDF (models/network_sdf.py contract) and sphere traced in-shader by lib/sdf.

The network and its safe step (the Lipschitz bound behind ``trace.step_scale``, softplus folded for
codegen) are models/mlp_sdf.py; the training points with exact signed distances, the fit and the
held-out metrics are models/mlp_sdf_fit.py. Here: the presets, the asset folder (bundle,
metrics.json, optional GL preview) and the command line.

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
from inshade.mesh import DEFAULT_OUT as DEFAULT_MESH

from inshade.models.mlp_sdf import ACTIVATIONS
from inshade.models.mlp_sdf_fit import DEFAULTS as FIT_DEFAULTS, SIGMAS, fit_mesh
from inshade.models.threads import torch_threads

KIND = "neural_sdf"
DEFAULTS = dict(out=None, mesh=None, **FIT_DEFAULTS, threads=1)
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
    with torch_threads(threads):
        return _train(out, mesh, width, layers, freqs, activation, steps, batch, lr, samples, seed,
                      lipschitz_target, lipschitz_weight, hit_eps, albedo, command, progress, mc_resolution, preview,
                      torch.device(device), preset)


def _train(out, mesh, width, layers, freqs, activation, steps, batch, lr, samples, seed, lipschitz_target,
           lipschitz_weight, hit_eps, albedo, command, progress, mc_resolution, preview, device, preset):
    if mesh is None:
        from inshade.mesh import write_bunny

        mesh = DEFAULT_MESH if DEFAULT_MESH.is_file() else write_bunny(DEFAULT_MESH)
    mesh_path = Path(mesh)
    result = fit_mesh(mesh_path, width=width, layers=layers, freqs=freqs, activation=activation, steps=steps,
                      batch=batch, lr=lr, samples=samples, seed=seed, lipschitz_target=lipschitz_target,
                      lipschitz_weight=lipschitz_weight, hit_eps=hit_eps, albedo=albedo, name=KIND,
                      progress=progress, mc_resolution=mc_resolution, device=device)
    module, metrics, tri = result.module, result.metrics, result.mesh
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
