"""`inshade train prt`: build a shipped PRT asset folder from one geometry.

    inshade train prt --sdf trained/sdf_creature/sdf.json        # -> ./inshade-out/prt_creature
    inshade train prt --neural-sdf trained/prt_neural_bunny/sdf  # -> ./inshade-out/prt_neural_bunny
    inshade train prt --mesh trained/prt_mesh/mesh.ply           # -> ./inshade-out/prt_mesh
    inshade train prt --gltf scene.glb                           # -> ./inshade-out/prt_scene

``--out DIR`` writes elsewhere; a folder that already holds files (a shipped asset) is refused
unless ``--force``.

Steps, all timed and recorded in ``OUT/metrics.json``:

1. the geometry is copied into OUT (unless it is already there; a glTF file as ``source.glb`` /
   ``source.gltf``, byte-identical);
2. ground-truth transfer data + the transfer network (techniques/prt/transfer_net.py, same options;
   the dataset cache lives outside the asset, in ``--cache``);
3. ``OUT/scene.json``: the PRT pass for the geometry (sdf_prt or mesh_prt) with the settings
   ``PRT_SETTINGS`` below, the camera of ``--camera-from`` (a scene.json) or an orbit framing the
   geometry's bound;
4. previews (diffuse and glossy PNG, rendered by the GL driver through ``inshade render``'s path);
5. quality against the per-pixel ground-truth-transfer render over an orbit (``techniques/prt/twin.py``
   ``quality_orbit``: PSNR / SSIM / MAE, diffuse and glossy).

``--gltf FILE``: the transfer is learnt for the file's world-space mesh (with its own normals), and the
scene draws the file through passes/mesh_prt_gltf.frag: PRT with the albedo of the file's base colour
(texture x factor, linear) next to the file's reference shading, ``view`` prt | reference | split |
albedo (techniques/prt/gltf_asset.py: previews, the quality with per-pixel albedo, and the PSNR of
PRT against the reference at the scene's camera, which differ by design: see the scene's notes).
An unreadable file is one ``inshade: error: FILE: FIELD: problem`` line before any work.

``--device auto|cpu|cuda[:N]`` (resolved before anything else): where step 2 runs -- the SDF
sphere tracing of the transfer rays (mesh rays are embree's, on the CPU) and the network's
training; the resolved device is recorded in the transfer bundle's provenance and metrics.

``--workers N`` / ``--ray auto|ADDRESS``: where the ground-truth rays of step 2 are baked, shard by
shard (models/bake.py, docs/cluster.md); the data is bit-identical to an in-process bake.

``--preset quick|ship`` (default ship): the settings of techniques/prt/recipes.py, options given
explicitly override them. ``ship`` is exactly what built the shipped assets: ``--recipe NAME`` takes
that asset's recipe, by default the one OUT is named after (``prt_creature``, ``prt_mechanical``,
``prt_mesh``, ``prt_neural_bunny``, ``prt_plants``), any other OUT the base recipe. ``metrics.json``
records the preset, the recipe and the resolved settings.

    inshade train prt --preset ship --sdf trained/prt_creature/sdf.json --out /tmp/prt_creature
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import shlex
import shutil
import time
from pathlib import Path

from inshade.files import atomic_write
from inshade.geometry.gltf import GltfError
from inshade.models.bake import BakeError, executor_from_args
from inshade.lit_settings import lit_settings
from inshade.scene.builder import display_modes, network, network_sdf, requires, scene_json, sky
from inshade.trainer import Run, Trainer, recorded

from inshade.techniques.prt import transfer_net
from inshade.techniques.prt.recipes import PRESETS, SHIP_ASSETS, Settings, recipe_for
from inshade.techniques.prt.recipes import QUICK, SHIP_BASE  # noqa: F401  (the recipes' values, read from here too)

# The PRT scene's user-facing settings (uniforms of lib/prt.glsl, the environment of lib/sdf).
PRT_SETTINGS = {
    **lit_settings(),
    "shading": {"type": "choice", "default": "diffuse", "choices": ["diffuse", "glossy"], "uniform": "u_shading",
                "label": "material"},
    "phong_exponent": {"type": "float", "default": 16.0, "min": 0.0, "max": 256.0, "uniform": "u_phong_exponent",
                       "label": "Phong exponent"},
    "albedo": {"type": "float", "default": 1.0, "min": 0.0, "max": 2.0, "uniform": "u_albedo",
               "label": "albedo tint"},
    "kd": {"type": "float", "default": 1.0, "min": 0.0, "max": 1.0, "uniform": "u_kd", "label": "kd"},
    "ks": {"type": "float", "default": 0.5, "min": 0.0, "max": 1.0, "uniform": "u_ks", "label": "ks"},
    "storage": {"type": "choice", "default": "auto", "choices": ["auto", "inline", "ubo", "texture"],
                "codegen": "storage", "label": "weight storage"},
}
PROGRAMS = {"sdf": "passes/sdf_prt.frag", "neural_sdf": "passes/sdf_prt.frag", "mesh": "passes/mesh_prt.frag",
            "gltf": "passes/mesh_prt_gltf.frag"}
GEOMETRY_OPTIONS = ("sdf", "neural_sdf", "mesh", "gltf")
PREVIEW_SIZE = 256
CACHE = Path.home() / ".cache" / "inshade" / "transfer"     # the transfer data's default cache


def _given(args) -> tuple[str, Path]:
    """(kind, path) of the one geometry option given."""
    given = [(k, getattr(args, k)) for k in GEOMETRY_OPTIONS if getattr(args, k)]
    if len(given) != 1:
        raise SystemExit("inshade train prt: give exactly one of --sdf, --neural-sdf, --mesh, --gltf")
    kind, path = given[0]
    return kind, Path(path)


def _geometry(args) -> tuple[str, Path]:
    """(kind, path) of the geometry, checked: a file that cannot be used fails before any work."""
    kind, path = _given(args)
    if kind == "gltf":   # read once up front: a bad file is one GltfError line before any work
        from inshade.techniques.prt.gltf_geometry import gltf_mesh

        gltf_mesh(path)
    if not path.exists():
        raise SystemExit(f"inshade train prt: {path}: no such file or folder")
    return kind, path


def default_name(src: Path) -> str:
    """The asset's name when no --out is given: prt_ + the geometry's name (the file's stem, or for
    a file or bundle called sdf/mesh its folder's name, without an sdf_/prt_ prefix)."""
    name = src.parent.name if src.stem in ("sdf", "mesh") else src.stem
    for prefix in ("prt_", "sdf_"):
        name = name.removeprefix(prefix)
    return f"prt_{name}"


def _copy_geometry(kind: str, src: Path, out: Path) -> str:
    """Copy the geometry into the asset; returns its name relative to OUT."""
    if kind == "gltf":
        from inshade.geometry.gltf import copy_gltf

        return copy_gltf(src, out)
    name = {"sdf": "sdf.json", "neural_sdf": "sdf", "mesh": "mesh" + src.suffix.lower()}[kind]
    dst = out / name
    if src.resolve() != dst.resolve():
        if src.is_dir():
            shutil.copytree(src, dst, dirs_exist_ok=True)
        else:
            shutil.copyfile(src, dst)
    return name


def scene_camera(center, radius, camera_from: str | None) -> tuple[dict, dict]:
    """(camera, bookmarks): those of the scene.json ``camera_from``, else an orbit framing the bound."""
    if camera_from:
        base = json.loads(Path(camera_from).read_text())
        return base["camera"], base.get("bookmarks", {})
    return {"type": "orbit", "fov_y": 40.0, "target": [float(c) for c in center],
            "distance": float(radius) * 2.9, "yaw": -30.0, "pitch": -18.0}, {}


def write_previews(out: Path) -> float:
    """preview.png / preview_glossy.png of OUT's scene through the GL driver; the seconds it took."""
    from inshade.runtime.headless import render_scene, save_render
    from inshade.scene.description import load_scene

    start = time.perf_counter()
    scene = load_scene(out)
    for shading, fname in (("diffuse", "preview.png"), ("glossy", "preview_glossy.png")):
        image, info = render_scene(scene, settings={"shading": shading})
        save_render(image, info, out / fname)
        (out / (fname + ".json")).unlink(missing_ok=True)  # the sidecar names local paths
    return time.perf_counter() - start


def previews_and_quality(out: Path, views: int, size: int, dirs: int) -> tuple[dict, dict]:
    """Previews, then the quality orbit of OUT's scene (twin.py quality_orbit, per-view rows dropped):
    (quality, {"preview_seconds", "quality_seconds"})."""
    from inshade.scene.description import load_scene
    from inshade.techniques.prt.twin import quality_orbit

    times = {"preview_seconds": write_previews(out)}
    start = time.perf_counter()
    quality = quality_orbit(load_scene(out), n_views=views, size=size, n_dirs=dirs, progress=None)
    times["quality_seconds"] = time.perf_counter() - start
    for mode in ("diffuse", "glossy"):
        quality[mode].pop("views", None)
    return quality, times


def scene_dict(kind: str, geometry_name: str, name: str, title: str, camera: dict, bookmarks: dict) -> dict:
    if kind == "gltf":
        from inshade.techniques.prt.gltf_asset import gltf_scene

        return gltf_scene(scene_dict("mesh", geometry_name, name, title, camera, bookmarks), PROGRAMS[kind])
    geometry = ({"mesh": geometry_name} if kind == "mesh" else
                {"sdf": network_sdf(geometry_name)} if kind == "neural_sdf" else {"sdf": geometry_name})
    return prt_scene(name, title, PROGRAMS[kind], PREVIEW_SIZE, [network("transfer", "transfer")], geometry,
                     camera, bookmarks)


def prt_scene(name: str, title: str, program: str, size: int, networks: list, geometry: dict, camera: dict,
              bookmarks: dict) -> dict:
    """A PRT asset's scene: its transfer network(s) over its geometry, lit by the noon sky."""
    return scene_json(name, title, program, (size, size), networks=networks, **geometry, camera=camera,
                      bookmarks=bookmarks, lights=[], environment=sky("noon"), display=display_modes("final"),
                      settings=PRT_SETTINGS, requires=requires())


# Options the recorded command leaves out: the device is recorded resolved in the transfer bundle's
# provenance, not in the recipe; where the bake ran (--workers, --ray) and where it is cached
# (--cache, --checkpoint) change nothing.
UNRECORDED = frozenset({"func", "command", "device", "workers", "ray", "force", "cache", "checkpoint"})


def train(run: Run) -> int:
    """The asset: geometry, transfer network (transfer_net.run), scene, previews, quality, metrics.json."""
    from inshade.bundle import load
    from inshade.techniques.prt.transfer_dataset import geometry_bound

    args, s, out = run.args, run.settings, run.out
    kind, src = _given(args)
    settings = {k: v for k, v in recorded(s).items() if k != "recipe"}   # the recipe's values, not its name
    # every option written out, the settings resolved: the command alone rebuilds the asset
    command = shlex.join(["inshade", "train", "prt"] + transfer_net.command_options(
        argparse.Namespace(**{**vars(args), **settings, "out": str(out)}), set(vars(args)) - UNRECORDED))
    out.mkdir(parents=True, exist_ok=True)
    times = {}
    geometry_name = _copy_geometry(kind, src, out)
    transfer_args = argparse.Namespace(**{
        **vars(args), **dataclasses.asdict(s), kind: str(out / geometry_name), "out": str(out / "transfer"),
        "cache": args.cache or str(CACHE)})
    if not args.skip_train:
        start = time.perf_counter()
        status = transfer_net.run(transfer_args)
        times["transfer_seconds"] = time.perf_counter() - start
        if status:
            return status
    geometry, _ = transfer_net.load_geometry(transfer_args)
    camera, bookmarks = scene_camera(*geometry_bound(geometry), s.camera_from)
    scene = scene_dict(kind, geometry_name, out.name, s.title or f"PRT: {out.name}", camera, bookmarks)
    atomic_write(out / "scene.json", json.dumps(scene, indent=1) + "\n")
    extra = {}
    if kind == "gltf":
        from inshade.techniques.prt.gltf_asset import gltf_previews_and_quality

        quality, extra, shown = gltf_previews_and_quality(out, s.quality_views, s.quality_size, s.quality_dirs,
                                                          PREVIEW_SIZE)
    else:
        quality, shown = previews_and_quality(out, s.quality_views, s.quality_size, s.quality_dirs)
    times.update(shown)
    bundle = load(out / "transfer")
    metrics = {"asset": out.name, "geometry": kind, "command": command, "preset": run.preset, "recipe": s.recipe,
               "settings": settings, "transfer": bundle.meta.get("metrics", {}),
               "provenance": bundle.meta.get("provenance", {}), "quality": quality, **extra, **times}
    atomic_write(out / "metrics.json", json.dumps(metrics, indent=1, sort_keys=True) + "\n")
    print(json.dumps({"quality": {m: quality[m] for m in ("diffuse", "glossy")}, **extra, **times}, indent=1))
    return 0


def extra_arguments(parser: argparse.ArgumentParser) -> None:
    """The geometry and where its data is baked and cached (transfer_net.py), and --skip-train."""
    transfer_net.add_inputs(parser, cache=str(CACHE).replace(str(Path.home()), "~"))
    parser.add_argument("--skip-train", action="store_true",
                        help="keep OUT/transfer, redo scene/previews/quality (an existing OUT: with --force)")


def folder(settings: Settings, args: argparse.Namespace) -> str:
    return default_name(_given(args)[1])


class RecipeTrainer(Trainer):
    """The trainer contract, with what holds before the asset folder is claimed: the geometry and the
    bake's options are checked, and the recipe not given is the one the asset folder is named after."""

    def resolve(self, args: argparse.Namespace) -> Settings:
        executor_from_args(args)          # a bad --workers / --ray fails before any work
        _, src = _geometry(args)
        if args.recipe is None:
            name = Path(args.out).name if args.out else default_name(src)
            args = argparse.Namespace(**{**vars(args), "recipe": recipe_for(name)})
        return super().resolve(args)


TRAINER = RecipeTrainer("prt", __doc__, Settings, PRESETS, train, folder=folder, default_preset="ship",
                        ship_assets=SHIP_ASSETS, extra_arguments=extra_arguments, errors=(BakeError, GltfError),
                        preset_by="recipe", folder_hint="prt_<geometry>")
add_arguments, main = TRAINER.add_arguments, TRAINER.main


def preset_settings(preset: str, asset: str | None = None) -> dict:
    """What ``--preset`` resolves to for an asset folder called ``asset`` (a shipped asset's name
    takes its recipe, any other the base recipe), as metrics.json records it: the recipe's values."""
    values = TRAINER.preset_settings(preset, asset if asset in SHIP_ASSETS else None)
    del values["recipe"]
    return values
