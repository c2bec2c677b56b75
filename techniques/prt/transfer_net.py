"""The learnt-transfer network (Learnt Transfer, Dhawal et al. 2022): sigma(p, n) -> 16 SH coefficients of transfer.

The command line that bakes ground-truth transfer data (techniques/prt/transfer.py ``build_dataset``)
for an SDF, a mesh, a glTF file's mesh or a network SDF, trains the network on it (techniques/prt/transfer_training.py)
and writes its bundle (techniques/prt/transfer_model.py, where the bundle's contract is):
python -m inshade.techniques.prt.transfer_net. `inshade train prt` runs it first, then builds the asset.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import shlex
import sys
from pathlib import Path

import torch

from inshade import command

from inshade.models import bake
from inshade.devices import DeviceError, add_device_argument, resolve_device

from inshade.techniques.prt.transfer_model import export_transfer
from inshade.techniques.prt.transfer_training import DEFAULTS, EVAL_SKY, train_transfer, training_config
from inshade.provenance import recorded_at


def command_options(args: argparse.Namespace, names) -> list[str]:
    """The options of ``args`` named in ``names`` as a re-runnable argv (flags only when set)."""
    out = []
    for k, v in sorted(vars(args).items()):
        if k not in names or v is None or v is False:
            continue
        out.append(f"--{k.replace('_', '-')}" if v is True else f"--{k.replace('_', '-')}={v}")
    return out


def load_geometry(args: argparse.Namespace):
    """(geometry, description) from --sdf / --mesh / --neural-sdf; ValueError naming the file."""
    if args.sdf:
        from inshade.geometry.sdf import load_sdf

        from inshade.models.sdf import SdfModule

        return SdfModule(load_sdf(args.sdf)), {"sdf": str(args.sdf)}
    if args.mesh:
        from inshade.techniques.prt.transfer_inputs import TransferError

        import trimesh

        path = Path(args.mesh)
        if not path.is_file():
            raise TransferError(f"{path}: mesh: no such file")
        try:
            mesh = trimesh.load(str(path), force="mesh", process=True)
        except Exception as exc:  # trimesh raises many types for bad files
            raise TransferError(f"{path}: mesh: cannot load ({exc})") from None
        if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
            raise TransferError(f"{path}: mesh: no triangles")
        return mesh, {"mesh": str(path)}
    if getattr(args, "gltf", None):
        from inshade.techniques.prt.gltf_geometry import gltf_mesh

        return gltf_mesh(args.gltf), {"gltf": str(args.gltf)}
    from inshade.bundle import load

    from inshade.models.network_sdf import NetworkSdfModule  # the neural-SDF twin (models/network_sdf.py)

    return NetworkSdfModule.from_bundle(load(args.neural_sdf)), {"neural_sdf": str(args.neural_sdf)}


def add_inputs(parser: argparse.ArgumentParser, cache: str = "OUT/../.transfer_cache") -> argparse.ArgumentParser:
    """The options that are not the network's settings: the geometry, where data and checkpoints are
    cached (``cache``: the default cache folder, as --help says it), where the rays are baked and on how
    many CPU threads (``inshade train prt`` has them too)."""
    geo = parser.add_mutually_exclusive_group(required=True)
    geo.add_argument("--sdf", help="analytic SDF description (e.g. trained/sdf_creature/sdf.json)")
    geo.add_argument("--mesh", help="triangle mesh (OBJ/PLY/GLB), transfer by embree ray casting")
    geo.add_argument("--neural-sdf", help="network-SDF bundle folder")
    geo.add_argument("--gltf", help="glTF 2.0 file (.glb/.gltf): transfer for its world-space mesh, read with its "
                                    "own normals; `inshade train prt` shades it with the file's base colour")
    parser.add_argument("--cache", default=None, help=f"dataset cache folder (default: {cache})%(default).0s")
    parser.add_argument("--checkpoint", default=None,
                        help="resumable checkpoint (default: CACHE/checkpoint-HASH.safetensors, HASH of the "
                             "dataset and the training settings, so a rerun resumes or finds it done)%(default).0s")
    bake.add_arguments(parser)
    parser.add_argument("--threads", type=int, default=DEFAULTS["threads"],
                        help="torch CPU threads; 0 = torch's default (default: %(default)s: on a shared 2-core "
                             "machine two spinning OpenMP threads ran rays and training ~10x slower than one)")
    return parser


def add_arguments(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """This module's options: its inputs, the bundle folder, the network's settings and the device."""
    d = DEFAULTS
    add_inputs(parser)
    parser.add_argument("--out", required=True, help="bundle folder to write")
    parser.add_argument("--width", type=int, default=d["width"], help="hidden width k (default: %(default)s)")
    parser.add_argument("--layers", type=int, default=d["layers"], help="hidden layers (default: %(default)s)")
    parser.add_argument("--points", type=int, default=d["points"], help="surface samples (default: %(default)s)")
    parser.add_argument("--dirs", type=int, default=d["dirs"], help="visibility rays per sample (default: %(default)s)")
    parser.add_argument("--steps", type=int, default=d["steps"], help="optimizer steps (default: %(default)s)")
    parser.add_argument("--batch", type=int, default=d["batch"], help="samples per step (default: %(default)s)")
    parser.add_argument("--lr", type=float, default=d["lr"], help="Adam learning rate (default: %(default)s)")
    parser.add_argument("--pos-freqs", type=int, default=d["pos_freqs"], help="position octaves (default: %(default)s)")
    parser.add_argument("--normal-freqs", type=int, default=d["normal_freqs"], help="normal octaves (default: %(default)s)")
    parser.add_argument("--output", choices=("tanh", "identity"), default=d["output"],
                        help="output activation (tanh: targets scaled by 1/1.25) (default: %(default)s)")
    parser.add_argument("--near-points", type=int, default=None,
                        help="further training samples drawn near occluders (SDFs: contact shadows, slots; "
                             "techniques/prt/transfer.py NEAR_BOOST / NEAR_DELTA), cast with --dirs rays; the "
                             "held-out samples stay uniform (default: %(default)s)")
    parser.add_argument("--drop-enclosed", action="store_true",
                        help="train without samples whose every visibility ray is blocked (enclosed shells)")
    parser.add_argument("--seed", type=int, default=d["seed"], help="random seed (default: %(default)s)")
    parser.add_argument("--precision", choices=("f32", "f16", "i8"), default=None,
                        help="dense weight storage; f16 / i8 end the fit with a quantization-aware fine-tune "
                             "(default: f32)")
    parser.add_argument("--finetune-steps", type=int, default=200,
                        help="steps of the quantization-aware fine-tune (default: %(default)s)")
    add_device_argument(parser)
    return parser


def _run_hash(data: dict, args: argparse.Namespace) -> str:
    config = training_config(args.width, args.layers, args.pos_freqs, args.normal_freqs, args.output, args.steps,
                     args.batch, args.lr, args.seed, args.drop_enclosed)
    return hashlib.sha256((data["key"] + json.dumps(config, sort_keys=True)).encode()).hexdigest()[:16]


def run(args: argparse.Namespace) -> int:
    from inshade.techniques.prt.transfer import build_dataset

    device = resolve_device(args.device)   # first: a CUDA the machine lacks fails before any work
    executor = bake.executor_from_args(args)
    for k in ("width", "layers", "points", "dirs", "steps", "batch"):
        if getattr(args, k) < 1:
            raise SystemExit(f"--{k} must be >= 1")
    if getattr(args, "near_points", None) is not None and args.near_points < 0:
        raise SystemExit("--near-points must be >= 0")
    if args.threads > 0:
        torch.set_num_threads(args.threads)
    geometry, source = load_geometry(args)
    out = Path(args.out)
    cache = Path(args.cache) if args.cache else out.parent / ".transfer_cache"
    near = getattr(args, "near_points", None) or 0
    data = build_dataset(geometry, args.points, args.dirs, cache, args.seed, progress=None, device=device,
                         executor=executor, near_points=near)
    print(f"data ({bake.describe(executor)}): {args.points} points{f' + {near} near occluders' if near else ''} x "
          f"{args.dirs} rays, {data['seconds']:.1f} s, "
          f"{data['rays_per_second'] / 1e3:.1f} k rays/s{' (cached)' if data['cached'] else ''}")
    net, frame, metrics = train_transfer(
        data, width=args.width, layers=args.layers, steps=args.steps, batch=args.batch, lr=args.lr,
        seed=args.seed, checkpoint=args.checkpoint or (cache / f"checkpoint-{_run_hash(data, args)}.safetensors"),
        progress=None,
        pos_freqs=args.pos_freqs, normal_freqs=args.normal_freqs, output=args.output,
        drop_enclosed=args.drop_enclosed, device=device, precision=getattr(args, "precision", None) or "f32",
        finetune_steps=getattr(args, "finetune_steps", 0))
    metrics.update({"data_seconds": data["seconds"], "rays_per_second": data["rays_per_second"],
                    "points": args.points, "dirs": args.dirs})
    if near:
        metrics["near_points"] = near
    # not a wrapper's options; the device goes into the provenance, resolved, not into the recipe; where
    # data and checkpoints are cached changes nothing in the result and names one machine's folders
    own = {a.dest for a in add_arguments(argparse.ArgumentParser())._actions} - {
        "help", "device", "workers", "ray", "cache", "checkpoint"}
    # this module's own command, every option written out (the asset's metrics.json holds the builder's)
    command = shlex.join(["python", "-m", "inshade.techniques.prt.transfer_net"] + command_options(args, own))
    provenance = {**source, "command": command, "dataset_key": data["key"],
                  "estimator": "cosine-weighted Fibonacci lattice, per-point Cranley-Patterson shift",
                  "loss": "l1 on transfer / scale", "optimizer": "adam, cosine decay to 5%",
                  "device": str(device), "torch": torch.__version__,
                  **recorded_at()}
    name = getattr(getattr(geometry, "scene", None), "name", "") or "transfer"
    export_transfer(net, frame, out, metrics, provenance, name=f"{name}_transfer",
                    precision=getattr(args, "precision", None) or "f32")
    resumed = (f" (went on from step {metrics['resumed_from']} of a checkpoint)"
               if metrics["resumed_from"] else "")
    print(f"wrote {out}: k={args.width}, {metrics['train_seconds']:.1f} s training{resumed}; held-out L1 "
          f"{metrics['heldout_l1']:.5f}, transfer PSNR {metrics['heldout_psnr']:.2f} dB, diffuse PSNR "
          f"{metrics['heldout_diffuse_psnr']:.2f} dB ({EVAL_SKY} sky)")
    return 0


def main(argv=None) -> int:
    from inshade.geometry.gltf import GltfError

    return command.main("python -m inshade.techniques.prt.transfer_net", __doc__, add_arguments, run, argv,
                        errors=(DeviceError, bake.BakeError, GltfError))


if __name__ == "__main__":
    sys.exit(main())
