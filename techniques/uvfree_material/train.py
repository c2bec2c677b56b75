"""Train a UV-free neural material (Walloner 2024): a hashed per-triangle feature hierarchy + MLP
fitted to a uv-textured mesh, written as an asset folder the runtime renders.

Command: ``inshade train uvfree_material [--object rock|fruit|stump_low|stump_high | --mesh FILE
--textures DIR | --gltf FILE] [--config memory|balanced|quality] [--preset quick|ship]
[--device auto|cpu|cuda[:N]] [--out DIR] [--resolution N] [--steps N] [--levels L] [--table-size T]
[--seed S]``.

- Targets: the mesh's own uv textures (``albedo.png`` sRGB, ``normal.png`` tangent-space
  n * 0.5 + 0.5, ``rma.png`` roughness/metallic/AO), looked up bilinearly (clamp) at the uv of
  each training point; the network learns the texel values as stored (model.py CHANNELS). A mesh
  without uv cannot provide targets: one error line.
- Points: triangles drawn by area (Vose alias table, O(1) per sample), barycentrics uniform on
  the triangle (t0 = 1 - sqrt(r0), t1 = sqrt(r0) (1 - r1)); fresh every step.
- Adam (betas 0.9, 0.99, as the thesis) on the feature table and the MLP, MSE, cosine decay.
- The mesh is read back through the runtime's loader (geometry/mesh.py load_mesh) before training,
  so triangle ids are the faces the renderer draws; the bundle records the welded topology's
  digest and the scene refuses a mesh that does not match.
- ``--gltf FILE`` (.glb or .gltf): the targets are the file's material channels at each point's uv
  instead, on the file's own mesh, written as a glTF asset folder (gltf_train.py).

Asset folder (default ``trained/uvfree_material_<object>_<config>``): ``material/`` (the bundle:
fp16 feature table stored F16, owner tables, MLP), ``mesh.obj``, the three reference textures,
``scene.json``, ``metrics.json`` and ``preview.png``. Presets: ``ship`` built the shipped assets
(512^2 textures, the thesis's 4x64 ReLU decoder); ``quick`` is the same pipeline at 64^2 with a
2x32 decoder, for a few seconds (tests).
"""
from __future__ import annotations

import argparse
import json
import shlex
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from PIL import Image

from inshade import asset_folder
from inshade.components import ComponentError
from inshade.devices import resolve_device
from inshade.files import atomic_write
from inshade.scene.builder import (bool_setting, choice_setting, display_modes, float_setting, int_setting,
                                    network, orbit, point_light, requires, scene_json, sky, texture)
from inshade.scene.labels import split_labels
from inshade.lit_settings import lit_settings
from inshade.geometry.mesh import MeshError, load_mesh, mesh_uv
from inshade.geometry.gltf import GltfError
from inshade.geometry.mesh_topology import MeshTopologyError, mesh_topology
from inshade.metrics import psnr
from inshade.trainer import Run, Trainer, seed_setting, setting, steps_setting
from inshade.provenance import recorded_at

from . import objects
from .fitting import BUNDLE, SurfaceSampler, TrainError, fit, render_preview
from .gltf_train import write_gltf_material
from .gltf_source import GltfSourceError
from .memory import memory_report, reference_bytes
from .model import CONFIGS, FEATURES, GROUPS, HIDDEN, KIND, choose_levels, choose_table_size, material_graph
from .object_textures import sample_textures, write_object

class Widths(tuple):
    """A decoder's hidden layer widths, spelled ``64,64,64,64`` on the command line."""

    def __new__(cls, value=()):
        if isinstance(value, str):
            text = value
            try:
                value = [int(w) for w in text.split(",") if w.strip()]
            except ValueError:
                value = []
            if not value or min(value) < 1 or max(value) > 256:
                raise argparse.ArgumentTypeError(f"comma-separated widths 1..256, got {text!r}")
        return super().__new__(cls, value)

    def __str__(self) -> str:
        return ",".join(map(str, self))


@dataclass(frozen=True)
class Settings:
    """What a uvfree_material run is built from (metrics.json records it). Levels and table size
    follow from the mesh and the config; metrics.json records them beside."""
    object: str = setting("rock", "a procedural uv-textured object (with --mesh: the mesh's name)",
                          choices=objects.OBJECTS)
    config: str = setting("balanced", "memory | balanced | quality: features sized to 1/12, 1/6, 1/3 of the "
                          "uncompressed textures", choices=sorted(CONFIGS))
    resolution: int = setting(512, "procedural texture side, a power of two")
    steps: int = steps_setting(3000)
    batch: int = setting(1 << 14, "surface points per step")
    hidden: Widths = setting(Widths(HIDDEN), "hidden layer widths of the decoder MLP, comma-separated",
                             metavar="W,W,...")
    features: int = setting(FEATURES, "features per table entry F", choices=(1, 2, 4, 8))
    seed: int = seed_setting()
    lr: float = setting(1e-2, "feature table learning rate (Adam)")
    mlp_lr: float = setting(5e-3, "decoder MLP learning rate (Adam)")


# "ship" built the shipped assets (512^2 textures, the thesis's 4x64 ReLU decoder); "quick" is the
# same pipeline at 64^2 with a 2x32 decoder, for a few seconds (tests).
PRESETS = {"quick": dict(resolution=64, steps=120, batch=4096, hidden=Widths((32, 32))), "ship": {}}
# The inputs of each shipped asset (--object and --config beside --preset ship).
SHIP_ASSETS = {f"{KIND}_{name}_{config}": dict(object=name, config=config)
               for name, config in (("fruit", "balanced"), ("rock", "balanced"), ("stump_high", "balanced"),
                                    ("stump_high", "memory"), ("stump_high", "quality"),
                                    ("stump_low", "balanced"))}


# ---------------------------------------------------------------------------------------------
# targets and samples

def stored_textures(folder: Path) -> dict:
    """The reference textures as stored: 8-bit values / 255 (albedo stays sRGB-encoded), image
    order (objects.py conventions); all the same size."""
    out = {}
    for key in objects.TEXTURES:
        path = folder / objects.FILES[key]
        if not path.is_file():
            raise TrainError(f"{path}: missing (a uv-textured mesh needs {', '.join(objects.FILES[k] for k in objects.TEXTURES)})")
        try:
            out[key] = np.asarray(Image.open(path).convert("RGB"), np.float32) / 255.0
        except OSError as exc:
            raise TrainError(f"{path}: cannot read as an image: {exc}") from None
    shapes = {k: v.shape for k, v in out.items()}
    if len(set(shapes.values())) != 1:
        raise TrainError(f"{folder}: textures differ in size: {shapes}")
    return out


def targets(textures: dict, uv: np.ndarray) -> np.ndarray:
    looked = sample_textures(textures, uv)
    return np.concatenate([looked[k] for k in objects.TEXTURES], 1)


# ---------------------------------------------------------------------------------------------
# training

def prepare_asset(out: Path, *, object_name: str | None, mesh_path, textures_dir, resolution: int, seed: int):
    """Write the mesh and reference textures into ``out``; returns (mesh as the runtime loads it,
    stored textures)."""
    out.mkdir(parents=True, exist_ok=True)
    if mesh_path is None:
        write_object(objects.make_object(object_name, resolution, seed), out)
    else:
        try:
            mesh = load_mesh(mesh_path)
        except MeshError as exc:
            raise TrainError(str(exc)) from None
        if mesh_uv(mesh) is None:
            raise TrainError(f"{mesh_path}: the mesh has no texture coordinates: training targets are looked "
                             f"up in its uv textures (export it with uvs)")
        from inshade.geometry.mesh import obj_text

        atomic_write(out / objects.FILES["mesh"], obj_text(mesh))
        src = Path(textures_dir) if textures_dir else Path(mesh_path).parent
        stored_textures(src)   # checked before copying
        for key in objects.TEXTURES:
            if src.resolve() != out.resolve():
                atomic_write(out / objects.FILES[key], (src / objects.FILES[key]).read_bytes())
    mesh = load_mesh(out / objects.FILES["mesh"])
    if mesh_uv(mesh) is None:
        raise TrainError(f"{out / objects.FILES['mesh']}: the mesh has no texture coordinates")
    return mesh, stored_textures(out)


def evaluate(graph, sampler, textures, n: int, seed: int, device) -> dict:
    """PSNR per channel group and the mean normal angle on fresh area-weighted points (torch)."""
    rng = np.random.default_rng(seed + 7_777_777)
    face, t0, t1, uv = sampler(n, rng)
    want = targets(textures, uv)
    with torch.no_grad():
        x = torch.from_numpy(np.stack([face.astype(np.float32), t0, t1], 1)).to(device)
        got = graph(x).cpu().numpy()
    out = {f"psnr_{g}": round(psnr(got[:, a:b], want[:, a:b]), 3) for g, (a, b) in GROUPS.items()}
    n_got, n_want = (v[:, 3:6] * 2 - 1 for v in (got, want))
    cos = (n_got * n_want).sum(1) / np.maximum(np.linalg.norm(n_got, axis=1) * np.linalg.norm(n_want, axis=1), 1e-12)
    out["normal_mean_deg"] = round(float(np.degrees(np.arccos(np.clip(cos, -1, 1))).mean()), 3)
    return out


def train(*, object_name="rock", mesh_path=None, textures_dir=None, config="balanced", preset="ship", out=None,
          resolution=None, steps=None, batch=None, levels=None, table_size=None, features=None, hidden=None,
          seed=None, device="cpu", lr=None, mlp_lr=None, progress=None, command_line=None,
          write_preview=True, gltf_path=None) -> Path:
    """Train and write the asset folder; returns it. The keyword form of ``inshade train
    uvfree_material``: a setting left None is the preset's. `device`: a torch.device or a --device
    spelling (auto, cpu, cuda, cuda:N). `gltf_path`: learn a glTF file's materials (``--gltf``)."""
    device = resolve_device(device) if isinstance(device, str) else torch.device(device)
    named = gltf_path if gltf_path is not None else mesh_path
    given = dict(object=object_name if named is None else Path(named).stem, config=config,
                 resolution=resolution, steps=steps, batch=batch, hidden=None if hidden is None else tuple(hidden),
                 features=features, seed=seed, lr=lr, mlp_lr=mlp_lr)
    settings = Settings(**{**TRAINER.defaults(preset), **{k: v for k, v in given.items() if v is not None}})
    check(settings)
    out = Path(out) if out else asset_folder.default(folder_name(settings))
    source = ["--gltf", str(gltf_path)] if gltf_path is not None else ["--object", settings.object]
    command_line = command_line or shlex.join(["inshade", "train", KIND, *source, "--config", settings.config,
                                               "--preset", preset])
    options = argparse.Namespace(mesh=mesh_path, textures=textures_dir, gltf=gltf_path, levels=levels,
                                 table_size=table_size, no_preview=not write_preview)
    run = Run(settings, preset, device, out, command_line, options)
    if gltf_path is not None:
        write_gltf_material(run, progress)
    else:
        write_material(run, progress)
    return out


def write_material(run: Run, progress=None) -> dict:
    """Train on ``run.settings`` and write the asset folder ``run.out`` (metrics.json through the
    run, then preview.png unless --no-preview); returns the metrics beside the run's record."""
    s, args, device, out = run.settings, run.args, run.device, run.out
    hidden = tuple(s.hidden)
    started = time.perf_counter()
    mesh, textures = prepare_asset(out, object_name=s.object, mesh_path=args.mesh, textures_dir=args.textures,
                                   resolution=s.resolution, seed=s.seed)
    tex_res = textures["albedo"].shape[0]
    faces = np.asarray(mesh.faces)
    ref_bytes = reference_bytes(tex_res)
    levels = args.levels or choose_levels(len(faces), tex_res * tex_res)
    table_size = args.table_size or choose_table_size(CONFIGS[s.config] * ref_bytes, levels, s.features)
    torch.manual_seed(s.seed)
    graph = material_graph(mesh.vertices, faces, levels=levels, table_size=table_size, features=s.features,
                           hidden=hidden, seed=s.seed).to(device)
    sampler = SurfaceSampler(mesh)

    def batch(rng):
        face, t0, t1, uv = sampler(s.batch, rng)
        return np.stack([face.astype(np.float32), t0, t1], 1), targets(textures, uv)

    history = fit(graph, batch, s, device, f"uvfree_material {s.object} {s.config}", progress)
    steps = s.steps
    seconds = time.perf_counter() - started
    graph = graph.to("cpu")
    quality = evaluate(graph, sampler, textures, 1 << 16, s.seed, "cpu")
    topo = mesh_topology(mesh.vertices, faces)
    provenance = {"command": run.command, "preset": run.preset, "object": s.object, "config": s.config,
                  "resolution": tex_res, "levels": levels, "features": s.features, "table_size": table_size,
                  "hidden": list(hidden), "steps": steps, "batch": s.batch, "seed": s.seed, "lr": s.lr,
                  "mlp_lr": s.mlp_lr, "mesh_digest": topo.digest, "faces": int(len(faces)),
                  "torch": torch.__version__, "device": str(device),
                  **recorded_at()}
    bundle = graph.export(KIND, f"{s.object}_{s.config}", provenance=provenance, metrics=quality)
    # the fp16 table (what an RGBA16F texture holds) stored as F16: half the file, widened exactly at load
    bundle.tensors = {k: (v.astype(np.float16) if k.endswith(".table") and v.dtype.kind == "f" else v)
                      for k, v in bundle.tensors.items()}
    bundle.save(out / BUNDLE)
    memory = memory_report(bundle, tex_res)
    atomic_write(out / "scene.json", json.dumps(scene_description(out.name, s.object, s.config), indent=2) + "\n")
    metrics = {"train_seconds": round(seconds, 1), "train_threads": torch.get_num_threads(), "device": str(device),
               "levels": levels, "table_size": table_size, "features": s.features, "faces": int(len(faces)),
               "memory": memory, "torch_quality": quality, "history": history}
    run.write_metrics(metrics)
    if not args.no_preview:
        render_preview(out)
    return metrics


def scene_description(name: str, object_name: str, config: str) -> dict:
    from . import CHANNEL_VIEWS, VIEWS, WIREFRAME

    return scene_json(
        name, f"UV-free neural material: {object_name} ({config}), hashed per-triangle features + MLP",
        "passes/mesh_uvfree_material.frag", (320, 320),
        networks=[network(BUNDLE, "mat")],
        mesh=objects.FILES["mesh"],
        textures=[texture(f"u_uvf_{k}", objects.FILES[k], mipmaps=False, repeat=False) for k in objects.TEXTURES],
        camera=orbit((0.0, 0.0, 0.0), 3.4, 30.0, -20.0, fov_y=35.0),
        bookmarks={"close-up": orbit((0.3, 0.3, 0.3), 1.3, 35.0, -25.0, fov_y=35.0)},
        lights=[point_light((2.5, 3.0, 2.5), 14.0), point_light((-3.0, 1.5, 1.5), 6.0)],
        environment=sky("studio", degree=3),
        display=display_modes(),
        labels=split_labels("reference", "decoded"),
        settings={
            **lit_settings("studio"),
            "view": choice_setting("split", VIEWS, "view (split: left reference, right decoded)", uniform="u_uvf_view"),
            "channel": choice_setting("shaded", CHANNEL_VIEWS, "shaded, or one channel as stored (debug)",
                                      uniform="u_uvf_channel"),
            "wireframe": choice_setting("off", WIREFRAME, "overlay: mesh triangles | sub-triangles of a level",
                                        uniform="u_uvf_wireframe"),
            "wire_level": int_setting(1, 0, 7, "overlay level", uniform="u_uvf_wire_level"),
            "decoder": bool_setting(True, "decoder compiled in (off: the reference-only shader, for timing)",
                                    define="UVF_DECODER"),
            "error_scale": float_setting(4.0, 0.0, 64.0, "error scale", uniform="u_uvf_error_scale"),
            "lights": int_setting(2, 0, 4, "point lights", uniform="u_light_count"),
        },
        requires=requires(),
        notes="decoded | reference: the 'view' setting (channels as debug views); the mesh's uvs feed only "
              "the reference and the tangent frame, the decoder reads the visibility buffer",
    )


# ---------------------------------------------------------------------------------------------
# command line

class MeshOption(argparse.Action):
    """``--mesh FILE`` / ``--gltf FILE`` names the asset after the file: the recorded ``object`` is its name."""

    def __call__(self, parser, namespace, value, option_string=None):
        setattr(namespace, self.dest, value)
        namespace.object = Path(value).stem


def extra_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--mesh", action=MeshOption, help="instead of --object: a uv-mapped mesh (OBJ/PLY/GLB)")
    parser.add_argument("--textures", help="with --mesh: folder holding albedo.png, normal.png, rma.png "
                        "(default: the mesh's folder)")
    parser.add_argument("--gltf", action=MeshOption, metavar="FILE", dest="gltf",
                        help="instead of --object / --mesh: learn a glTF file's materials (.glb/.gltf; base colour, "
                        "metallic, roughness and the normal, occlusion and emission it has) on its own mesh")
    parser.add_argument("--levels", type=int, help="hierarchy levels L (default: from the texel density)")
    parser.add_argument("--table-size", type=int, help="hash-table entries per level T, a power of two "
                        "(default: from --config)")
    parser.add_argument("--no-preview", action="store_true", help="skip rendering preview.png")


def build_gltf(run: Run) -> int:
    args = run.args
    if args.mesh or args.textures:
        raise TrainError(f"--{'mesh' if args.mesh else 'textures'}: goes without --gltf (the file holds the mesh "
                         "and its textures)")
    if run.settings.object != Path(args.gltf).stem:
        raise TrainError("--object: goes without --gltf (the file names the asset)")
    m = write_gltf_material(run)
    q, mem, r = m["torch_quality"], m["memory"], m["render"]
    each = ", ".join(f"{k[5:]} {v:.2f}" for k, v in q.items() if k.startswith("psnr_"))
    size = (f"{mem['rate_features_mlp']:.1%} of its {mem['texture_bytes']} B of RGBA8 textures "
            f"({mem['rate_file']:.1%} of the {mem['texture_bytes_file']} B it stores)" if mem["texture_bytes"]
            else "(the file has no textures)")
    print(f"wrote {run.out}: channels {each} dB; render {r['render_psnr_vs_reference']:.2f} dB vs the file's "
          f"material; {mem['neural_bytes']} B features + MLP {size}; {m['train_seconds']:.0f} s")
    return 0


def check(s: Settings) -> None:
    if s.config not in CONFIGS:
        raise TrainError(f"--config: unknown {s.config!r} (choose from {', '.join(CONFIGS)})")
    if s.steps < 0:
        raise TrainError(f"--steps: must be >= 0, got {s.steps}")
    if s.batch < 1:
        raise TrainError(f"--batch: must be >= 1, got {s.batch}")


def folder_name(s: Settings) -> str:
    return f"{KIND}_{s.object}_{s.config}"


def build(run: Run) -> int:
    args = run.args
    for name in ("levels", "table_size"):
        v = getattr(args, name)
        if v is not None and v < 1:
            raise TrainError(f"--{name.replace('_', '-')}: must be >= 1, got {v}")
    if args.gltf:
        return build_gltf(run)
    if args.textures and not args.mesh:
        raise TrainError("--textures: goes with --mesh")
    if args.mesh and run.settings.object != Path(args.mesh).stem:
        raise TrainError("--object: goes without --mesh (the mesh names the asset)")
    m = write_material(run)
    q, mem = m["torch_quality"], m["memory"]
    print(f"wrote {run.out}: albedo {q['psnr_albedo']:.2f} dB, normal {q['normal_mean_deg']:.2f} deg, "
          f"rma {q['psnr_rma']:.2f} dB; {mem['rate_features_mlp']:.1%} of the textures "
          f"({mem['rate_all']:.1%} with owner tables); {m['train_seconds']:.0f} s")
    return 0


TRAINER = Trainer(KIND, __doc__, Settings, PRESETS, build, folder=folder_name, default_preset="ship",
                  ship_assets=SHIP_ASSETS, extra_arguments=extra_arguments, check=check,
                  errors=(TrainError, ComponentError, MeshTopologyError, objects.ObjectError, GltfSourceError, GltfError))
add_arguments, preset_settings, main = TRAINER.add_arguments, TRAINER.preset_settings, TRAINER.main
