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
(inshade.geometry.mesh.bunny) is generated into /tmp/inshade_mesh/bunny.ply first.
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import shlex
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from inshade import asset_folder
from inshade.geometry.mesh import DEFAULT_OUT as DEFAULT_MESH

from inshade.models.mlp_sdf import ACTIVATIONS
from inshade.models.mlp_sdf_fit import DEFAULTS as FIT_DEFAULTS, SIGMAS, fit_mesh
from inshade.models.threads import torch_threads
from inshade.trainer import Run, Trainer, lr_setting, seed_setting, setting
from inshade.provenance import recorded_at

KIND = "neural_sdf"
ALBEDO = (0.8, 0.8, 0.8)


@dataclass(frozen=True)
class Settings:
    """What a neural_sdf run is built from (metrics.json and the bundle's provenance record it; the
    mesh is an input beside it)."""
    width: int = setting(FIT_DEFAULTS["width"], "hidden width")
    layers: int = setting(FIT_DEFAULTS["layers"], "hidden layers")
    freqs: int = setting(FIT_DEFAULTS["freqs"], "frequency-encoding octaves, 0 = plain MLP")
    activation: str = setting(FIT_DEFAULTS["activation"], "hidden activation", choices=ACTIVATIONS)
    steps: int = setting(FIT_DEFAULTS["steps"], "optimizer steps")
    batch: int = setting(FIT_DEFAULTS["batch"], "points per step")
    lr: float = lr_setting(FIT_DEFAULTS["lr"])
    samples: int = setting(FIT_DEFAULTS["samples"], "training points")
    seed: int = seed_setting(FIT_DEFAULTS["seed"])
    lipschitz_target: float = setting(FIT_DEFAULTS["lipschitz_target"], "the penalty starts above this bound")
    lipschitz_weight: float = setting(FIT_DEFAULTS["lipschitz_weight"], "weight of the Lipschitz penalty, 0 = off")


# --preset: "ship" (the default) is what built the shipped network SDF (trained/prt_neural_bunny/sdf,
# on the procedural rabbit): 48 wide with two octaves of position encoding, the capacity that keeps
# thin parts apart (the rabbit's ears: a 32x3 plain MLP fused them; 48x3 + 2 octaves: 0.2% of the gap
# between them inside, was 21%; surface error 2.2e-3 r, was 6.8e-3 r); "quick" is a small fit for
# a smoke run (seconds).
PRESETS = {"ship": dict(steps=3000, samples=300_000, batch=8192, width=48, freqs=2),
           "quick": dict(steps=100, samples=10_000, batch=4096)}


class NeuralSdfError(ValueError):
    """A setting the network SDF trainer cannot use."""


def default_name(mesh) -> str:
    """The asset folder's name when no --out is given: neural_sdf_<mesh file stem>."""
    return f"{KIND}_{Path(mesh).stem if mesh else DEFAULT_MESH.stem}"


def mesh_or_rabbit(mesh) -> Path:
    """``mesh``, or without one the procedural rabbit (inshade.geometry.mesh.bunny), generated into
    DEFAULT_MESH the first time."""
    if mesh is None:
        from inshade.geometry.mesh import write_bunny

        mesh = DEFAULT_MESH if DEFAULT_MESH.is_file() else write_bunny(DEFAULT_MESH)
    return Path(mesh)


def train(*, out=None, mesh=None, width=FIT_DEFAULTS["width"], layers=FIT_DEFAULTS["layers"],
          freqs=FIT_DEFAULTS["freqs"], activation=FIT_DEFAULTS["activation"], steps=FIT_DEFAULTS["steps"],
          batch=FIT_DEFAULTS["batch"], lr=FIT_DEFAULTS["lr"], samples=FIT_DEFAULTS["samples"],
          seed=FIT_DEFAULTS["seed"], lipschitz_target=FIT_DEFAULTS["lipschitz_target"],
          lipschitz_weight=FIT_DEFAULTS["lipschitz_weight"], hit_eps=FIT_DEFAULTS["hit_eps"], albedo=ALBEDO,
          command: str | None = None, progress: bool | None = None, mc_resolution: int = 64,
          threads: int | None = 1, preview: bool = False, device="cpu", preset: str | None = None):
    """Fit (on ``device``, a torch.device or its name), evaluate and write the bundle into ``out``
    (+ metrics in it). Returns the Bundle.
    ``threads``: torch intra-op threads while fitting (1 by default: on a shared 2-core machine two
    spinning threads made each step ~15x slower than one; None leaves torch's setting)."""
    settings = Settings(width=width, layers=layers, freqs=freqs, activation=activation, steps=steps, batch=batch,
                        lr=lr, samples=samples, seed=seed, lipschitz_target=lipschitz_target,
                        lipschitz_weight=lipschitz_weight)
    mesh = mesh_or_rabbit(mesh)
    if command is None:    # the command line that repeats this call
        flags = {"out": out, "mesh": mesh, **dataclasses.asdict(settings)}
        command = shlex.join(["inshade", "train", KIND] + [
            s for k, v in flags.items() for s in (f"--{k.replace('_', '-')}", str(v))])
    out = Path(out) if out else asset_folder.default(default_name(mesh))
    run = Run(settings, preset, torch.device(device), out, command,
              argparse.Namespace(mesh=mesh, threads=threads, preview=preview))
    return fit_and_write(run, hit_eps=hit_eps, albedo=albedo, progress=progress, mc_resolution=mc_resolution)


def fit_and_write(run: Run, *, hit_eps=FIT_DEFAULTS["hit_eps"], albedo=ALBEDO, progress: bool | None = None,
                  mc_resolution: int = 64):
    """Fit ``run.settings`` to the mesh ``run.args.mesh`` on ``run.device`` with ``run.args.threads``
    torch threads, evaluate, and write ``run.out``: the bundle (its provenance records the command,
    preset and settings), metrics.json and, with ``run.args.preview``, preview.png. Returns the Bundle."""
    with torch_threads(run.args.threads):
        s, mesh_path = run.settings, mesh_or_rabbit(run.args.mesh)
        result = fit_mesh(mesh_path, **dataclasses.asdict(s), hit_eps=hit_eps, albedo=albedo, name=KIND,
                          progress=progress, mc_resolution=mc_resolution, device=run.device)
        module, metrics, tri = result.module, result.metrics, result.mesh
        provenance = {
            "command": run.command,
            "mesh": str(mesh_path), "mesh_faces": int(len(tri.faces)), "mesh_vertices": int(len(tri.vertices)),
            "sampling": f"{s.samples}: 1/4 on the surface, 1/2 surface + N(0, ({SIGMAS[0]}r, {SIGMAS[1]}r)), "
                        f"1/4 uniform in the bound's cube; exact signed distance (point-cloud-utils)",
            "loss": "L1 on distance / radius + lipschitz_weight * relu(log L - log target)",
            "optimizer": "adam, cosine decay to 2%", **dataclasses.asdict(s),
            "preset": run.preset,
            "device": str(run.device),
            "torch": torch.__version__,
            **recorded_at(),
        }
        bundle = module.export(KIND, KIND, provenance=provenance, metrics=metrics)
        bundle.save(run.out)
        run.write_metrics(metrics)
        if run.args.preview:
            from inshade.scene.image_io import write_png

            image, info = render_preview(bundle)
            write_png(run.out / "preview.png", image)
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
    from inshade.scene.camera import OrbitCamera
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

def extra_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--mesh", default=None,
                        help="watertight OBJ/PLY/GLB (default: the procedural rabbit, generated into "
                             f"{DEFAULT_MESH})")
    parser.add_argument("--preview", action="store_true",
                        help="also render preview.png through the GLSL path (headless EGL)")
    parser.add_argument("--threads", type=int, default=1, help="torch threads while fitting (default: %(default)s)")


def check(s: Settings) -> None:
    if s.steps < 0 or s.width < 1 or s.layers < 1 or s.samples < 100:
        raise NeuralSdfError("--steps must be >= 0, --width and --layers >= 1, --samples >= 100")


def train_command(run: Run) -> int:
    bundle = fit_and_write(run)
    m = bundle.meta["metrics"]
    print(f"wrote {bundle.path}: surface |d| {m['surface_abs_mean_rel']:.2e} r, IoU {m['iou_uniform']:.4f}, "
          f"Chamfer {m['chamfer_rel']:.2e} r, Lipschitz bound {m['lipschitz_bound']:.2f} -> step_scale "
          f"{m['step_scale']:.3f} ({m['params']} params; data {m['data_seconds']:.0f} s, "
          f"train {m['train_seconds']:.0f} s)")
    return 0


TRAINER = Trainer(KIND, __doc__, Settings, PRESETS, train_command, folder=lambda s, args: default_name(args.mesh),
                  folder_hint=f"{KIND}_<mesh>",
                  default_preset="ship", extra_arguments=extra_arguments, check=check, errors=(NeuralSdfError,))
add_arguments, preset_settings, main = TRAINER.add_arguments, TRAINER.preset_settings, TRAINER.main
