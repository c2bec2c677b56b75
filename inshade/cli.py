"""`inshade` command line: codegen, info, render, view, doctor, bench, train.

Bad input (a malformed bundle, an unknown option value, a shader that does not compile, a
missing GL capability) prints one `inshade: error: ...` line and exits with status 2.
"""
from __future__ import annotations

import argparse
import importlib
import json
import logging
import os
import signal
import sys
import tempfile
import threading
from pathlib import Path

log = logging.getLogger("inshade")

# Benchmarks of shared machinery (not of one technique); technique benches and trainers come
# from the technique registry (inshade/technique.py). name -> (module, help)
SHARED_BENCHES = {"mlp": ("inshade.bench.mlp", "MLP throughput: GLSL per storage mode vs torch CPU vs sgemm peak"),
                  "export": ("inshade.bench.export", "inshade.export / convert: export + check time, ONNX import "
                                                     "time, export peak memory"),
                  "web": ("inshade.web.bench", "every shipped asset as a WebGL2 page in headless Chromium: page bytes, "
                                               "load time, frame time, PSNR vs inshade render"),
                  "suite": ("inshade.bench.suite", "every bench, sized by --preset cpu|device, and a one-page "
                                                   "summary against the papers (docs/bench/<renderer>/)")}


def trainers() -> dict:
    """name -> (module, help) of every registered technique with a trainer."""
    from inshade import technique

    return {t.name: (t.train, t.train_help or t.summary) for t in technique.techniques() if t.train}


def aliases() -> dict:
    """command -> ("train", name): a technique's own top-level name for its trainer
    (``Technique.train_alias``, e.g. `inshade compress ...` runs a texture trainer)."""
    from inshade import technique

    return {t.train_alias: ("train", t.name) for t in technique.techniques() if t.train and t.train_alias}


def benches() -> dict:
    """name -> (module, help): the shared benches, then every registered technique's bench."""
    from inshade import technique

    out = dict(SHARED_BENCHES)
    out.update({t.name: (t.bench, t.bench_help or t.summary) for t in technique.techniques() if t.bench})
    return out


STDOUT = "-"   # -o -: standard output, where the format allows


class UserError(Exception):
    """Input the user can fix; reported in one line with exit status 2."""


class ArgumentParser(argparse.ArgumentParser):
    """argparse, but a bad command line is one `inshade: error: ...` line (exit 2), not a usage dump."""

    def error(self, message):
        command = self.prog.split(" ", 1)[1] + ": " if " " in self.prog else ""
        self.exit(2, f"inshade: error: {command}{' '.join(message.split())}\n")


def _int_at_least(minimum: int, not_int: str, too_small: str):
    """An argparse type: an int >= ``minimum``; the messages end with ``, got VALUE``."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{not_int}, got {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"{too_small}, got {value}")
        return value
    return parse


_count = _int_at_least(1, "must be an integer", "must be >= 1")   # --spp, --calls


def _size(text: str) -> int:
    """--width/--height: an int in 1..MAX_SIZE."""
    from inshade.scene.description import MAX_SIZE

    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer, got {text!r}") from None
    if not 1 <= value <= MAX_SIZE:
        raise argparse.ArgumentTypeError(f"must be in 1..{MAX_SIZE}, got {value}")
    return value


def check_output(path, option: str = "-o") -> Path:
    """Refuse an output path that cannot be written, before any work: its folder (or the first
    existing folder above it) must be a writable folder, and the path itself not a folder."""
    path = Path(path)
    if path.is_dir():
        raise UserError(f"{path}: {option}: is a folder, expected a file path")
    parent = path.parent
    while not parent.exists():
        if parent.is_symlink():
            raise UserError(f"{path}: {option}: {parent} is a dangling link")
        parent = parent.parent
    if not parent.is_dir():
        raise UserError(f"{path}: {option}: {parent} is a file, not a folder")
    if parent == path.parent:   # try exactly what the writer will do: a temporary file beside it
        try:
            fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".probe", dir=parent)
        except OSError as e:
            raise UserError(f"{path}: {option}: cannot write in {parent} ({e.strerror or e})") from None
        os.close(fd)
        os.unlink(tmp)
    elif not os.access(parent, os.W_OK | os.X_OK):
        raise UserError(f"{path}: {option}: cannot create folders in {parent} (not writable)")
    return path


def _one_line(text: str) -> str:
    """A message as one line: its lines joined with '; ' (e.g. a shader compiler's log)."""
    return "; ".join(line.strip() for line in text.splitlines() if line.strip())


def _write_error(path, e: OSError) -> UserError:
    """The error of a write that failed, naming the file that failed (one of a group, maybe)."""
    return UserError(f"{e.filename or path}: cannot write ({e.strerror or e})")


def _user_errors():
    from inshade.bundle import BundleError
    from inshade.components import ComponentError
    from inshade.shaders import ShaderCompileError, ShaderIncludeError
    from inshade.runtime.context import GLContextError
    return (UserError, BundleError, ComponentError, ShaderCompileError, ShaderIncludeError,
            GLContextError, ValueError)


# codegen ---------------------------------------------------------------------------------
def cmd_codegen(args) -> int:
    from inshade import bundle as bundle_mod

    if args.output not in (None, STDOUT):
        check_output(args.output)
    if Path(args.bundle).suffix.lower() == ".onnx":   # converted in memory (inshade convert writes it)
        from inshade.convert.onnx_model import to_bundle

        scene, b = None, to_bundle(args.bundle)[0]
        if args.network is not None:
            raise UserError(f"{args.bundle}: --network picks a network of an asset; this is an ONNX file")
        return _codegen(args, b, args.prefix, args.output)
    src = _resolve(args.bundle)
    scene, nets = _asset_networks(src)
    prefix = args.prefix
    if args.program:
        return _codegen_program(args, src)
    if args.network == "all":
        if scene is None or not nets:
            raise UserError(f"{src}: --network all: needs an asset with networks (a folder with scene.json)")
        if args.output == STDOUT and len(nets) > 1:
            raise UserError(f"-o -: {len(nets)} networks would share standard output; write to a file (-o net.glsl "
                            "becomes net.PREFIX.glsl per network)")
        for role, net_prefix, bpath in nets:
            print(f"== network {net_prefix} ({role}, {Path(bpath).name})")
            out = args.output if args.output in (None, STDOUT) else str(
                Path(args.output).with_name(f"{Path(args.output).stem}.{net_prefix}{Path(args.output).suffix}"))
            _codegen(args, bundle_mod.load(bpath), net_prefix, out)
        return 0
    if scene is None:
        if args.network is not None:
            raise UserError(f"{src}: --network picks a network of an asset (a folder with scene.json); "
                            "this is a bundle")
        bpath = src
    else:
        chosen = _pick_network(args.bundle, scene, nets, args.network)
        bpath = chosen[2]
        prefix = prefix or chosen[1]
    return _codegen(args, bundle_mod.load(bpath), prefix, args.output)


def _resource_manifest(resources) -> tuple[list, dict]:
    """(manifest entries, {name: array}) of generated GL resources, for a .resources.safetensors."""
    import numpy as np

    from inshade.codegen.glsl import TextureResource

    entries, tensors = [], {}
    for res in resources:
        if isinstance(res, TextureResource):
            kind = "texture2d_array" if res.array else f"texture{res.dims}d"
            entries.append({"name": res.name, "kind": kind, "dtype": res.dtype, "filter": res.filter,
                            "shape": list(res.data.shape), "mips": [f"{res.name}.mip{k}" for k in range(1, res.levels)]})
            tensors[res.name] = res.data
            tensors.update({f"{res.name}.mip{k}": m for k, m in enumerate(res.mips, 1)})
        else:
            entries.append({"name": res.name, "kind": "uniform_block_std140", "bytes": res.nbytes})
            tensors[res.name] = np.frombuffer(res.data, "uint8")
    return entries, tensors


def _write_group(out: Path, text: str, manifest: dict, tensors: dict, extra: dict | None = None) -> list[Path]:
    """out (text), out.json (manifest), out's .resources.safetensors (when there are tensors) and any
    ``extra`` {path: text}: all together or none."""
    from safetensors.numpy import save_file

    from inshade.files import atomic_files

    rpath = out.with_suffix(".resources.safetensors")
    if tensors:
        manifest["resources_file"] = rpath.name
    extra = extra or {}
    paths = [out, out.with_suffix(out.suffix + ".json"), *extra] + ([rpath] if tensors else [])
    try:
        with atomic_files(*paths) as temps:
            temps[0].write_text(text)
            temps[1].write_text(json.dumps(manifest, indent=2, sort_keys=True) + "\n")
            for tmp, body in zip(temps[2:], extra.values()):
                tmp.write_text(body)
            if tensors:
                save_file(tensors, str(temps[-1]))
    except OSError as e:
        raise _write_error(out, e) from None
    return paths


def _codegen_program(args, src: Path) -> int:
    """--program: the scene's whole pass, includes resolved, and what to bind to it."""
    import numpy as np

    from inshade.runtime.context import shared_context
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import load_scene

    if args.output in (None, STDOUT):
        raise UserError("--program: give -o PASS.frag (the vertex stage, manifest and resources go beside it)")
    check_output(args.output)
    scene = load_scene(src)
    renderer = SceneRenderer(scene, shared_context(), settings={"storage": args.storage})
    try:
        sources = renderer.assembled()
        width, height = scene.size
        values = renderer.uniform_values(scene.make_camera(), width, height)
        entries, tensors = _resource_manifest([r for g in renderer.generated for r in g.resources])
    finally:
        renderer.release()
    uniforms = {name: (np.frombuffer(value, np.float32).tolist() if isinstance(value, (bytes, bytearray))
                       else list(value) if isinstance(value, tuple) else value) for name, value in values.items()}
    out = Path(args.output)
    vert = out.with_suffix(".vert") if out.suffix == ".frag" else out.with_name(out.stem + ".vert" + out.suffix)
    manifest = {"scene": str(src), "program": scene.program, "vertex_shader": vert.name,
                "size": [width, height], "uniforms": uniforms, "resources": entries,
                "note": "a fullscreen triangle (the vertex stage) drawing the fragment stage; bind the resources "
                        "under their names and set the uniforms (values of the scene's default view and settings)"}
    paths = _write_group(out, sources["fragment"], manifest, tensors, {vert: sources["vertex"]})
    for p in paths:
        print(f"wrote {p}", file=sys.stderr)
    return 0


def _codegen(args, b, prefix, output) -> int:
    from inshade.codegen import generate
    from inshade.shaders import flatten

    if args.no_gl:
        limits = {}
    else:   # plan against this machine's limits when it can make a context
        from inshade.runtime.context import machine_limits

        limits = machine_limits()
    gen = generate(b, storage=args.storage, target=args.target, prefix=prefix or "net",
                   lut_filter=args.lut_filter, texture_format=args.texture_format, limits=limits, calls=args.calls)
    if output == STDOUT:   # the GLSL alone on stdout; the plan goes to stderr
        if gen.resources:
            raise UserError(f"-o -: this GLSL binds {len(gen.resources)} resources "
                            f"({', '.join(r.name for r in gen.resources)}) that standard output cannot carry; "
                            "write to a file (-o net.glsl) or use --storage inline")
        print(gen.plan.report(), file=sys.stderr)
        sys.stdout.write(flatten("network", chunks={"network": gen.chunk}))
        return 0
    print(gen.plan.report())
    if output is None:
        return 0
    out = Path(output)
    entries, tensors = _resource_manifest(gen.resources)
    manifest = {"bundle": str(b.path if b.path is not None else args.bundle), "bundle_digest": b.digest(),
                "function": gen.function, "in_dim": gen.in_dim, "out_dim": gen.out_dim, "target": args.target,
                "plan": gen.plan.to_dict(), "resources": entries}
    # the GLSL, its manifest and its resources appear together or not at all
    _write_group(out, flatten("network", chunks={"network": gen.chunk}), manifest, tensors)
    print(f"wrote {out} ({len(gen.resources)} resources)", file=sys.stderr)
    return 0


# info -------------------------------------------------------------------------------------
def _resolve(name_or_path) -> Path:
    """An asset path, or a bare name looked up in trained/ and $INSHADE_ASSETS (scene/description.py)."""
    from inshade.scene.description import resolve_asset

    return resolve_asset(name_or_path)


def _asset_networks(src: Path):
    """(scene, [(role, prefix, bundle path)]) of an asset with a scene.json (its networks, then a
    network SDF), or (None, []) for a bare bundle."""
    from inshade.scene.description import NetworkSdfRef, is_scene, load_scene

    if not is_scene(src):
        return None, []
    scene = load_scene(src)
    nets = [("network", n.prefix, n.bundle) for n in scene.networks]
    if isinstance(scene.sdf, NetworkSdfRef):
        nets.append(("network SDF", scene.sdf.prefix, scene.sdf.bundle))
    return scene, nets


def _pick_network(src, scene, nets, prefix):
    prefixes = ", ".join(p for _, p, _ in nets)
    if not nets:
        raise UserError(f"{src}: scene '{scene.name}' uses no networks (e.g. an analytic SDF); nothing to generate")
    if prefix is not None:
        for net in nets:
            if net[1] == prefix:
                return net
        raise UserError(f"{src}: --network {prefix}: no such network (this asset has: {prefixes})")
    if len(nets) > 1:
        raise UserError(f"{src}: uses {len(nets)} networks; pick one with --network PREFIX ({prefixes})")
    return nets[0]


def _short(value) -> str:
    """A metrics/provenance value for the text output: scalars as they are, short lists of
    scalars inline, other lists and tables summarised (--json has them in full)."""
    if isinstance(value, list):
        if len(value) <= 4 and all(isinstance(v, (int, float, str, bool)) for v in value) \
                and len(str(value)) <= 60:
            return str(value)
        return f"{len(value)} values"
    if isinstance(value, dict):
        return f"{len(value)} entries"
    return str(value)


def _bundle_json(b, envelope) -> dict:
    from inshade.envelope import format_findings

    return {"meta": b.meta, "digest": b.digest(),
            "tensors": {k: [str(v.dtype), list(v.shape)] for k, v in sorted(b.tensors.items())},
            "converted": dict(sorted(b.converted.items())),
            "envelope": format_findings(envelope)}


def _describe_bundle(b, envelope, indent: str = "") -> None:
    from inshade.envelope import format_findings

    out = [f"{b.name}  (kind {b.kind}, format v{b.meta['version']})  sha256 {b.digest()[:16]}",
           "inputs:  " + ", ".join(f"{p.name}[{p.dim}] ({p.semantic})" for p in b.inputs),
           "outputs: " + ", ".join(f"{p.name}[{p.dim}] <- {p.node} ({p.semantic})" for p in b.outputs),
           "nodes:"]
    for n in b.nodes:
        params = ", ".join(f"{k}={v}" for k, v in n.params.items())
        out.append(f"  {n.id:<12} {n.type:<20} {n.in_dim:>4} -> {n.out_dim:<4} {params}")
    total = sum(v.nbytes for v in b.tensors.values())
    out.append(f"tensors: {len(b.tensors)}, {sum(v.size for v in b.tensors.values())} values, {total} bytes")
    if b.converted:
        stored = ", ".join(sorted(set(b.converted.values())))
        out.append(f"converted: {len(b.converted)} tensors stored as {stored}, widened to float32 at load (exact): "
                   + ", ".join(sorted(b.converted)))
    out.append("parity envelope: " + "; ".join(format_findings(envelope, notes=False)))
    summarised = False
    for key in ("metrics", "provenance"):
        if b.meta.get(key):
            out.append(f"{key}:")
            for k, v in sorted(b.meta[key].items()):
                summarised |= isinstance(v, (list, dict)) and _short(v) != str(v)
                out.append(f"  {k}: {_short(v)}")
    if summarised:
        out.append("(lists and tables summarised; --json has them in full)")
    for line in out:
        print(indent + line)


def _setting_rows(scene) -> list[str]:
    rows = []
    for s in scene.settings.values():
        if s.type == "choice":
            values = "|".join(str(c) for c in s.choices)
        elif s.type == "bool":
            values = "true|false"
        else:
            values = f"{s.min:g}..{s.max:g}"
        also = {"storage": "  (also --storage)", "lut_filter": "  (also --lut-filter)"}.get(s.name, "")
        label = f"  {s.label}" if s.label and s.label != s.name else ""
        default = json.dumps(s.default) if isinstance(s.default, bool) else s.default
        rows.append(f"  {s.name:<14} {s.type:<6} {values:<32} default {default}{label}{also}")
    return rows


def _sdf_summary(sdf) -> str:
    from collections import Counter

    counts, stack = Counter(), [sdf.root]
    while stack:
        node = stack.pop()
        counts[node.type] += 1
        stack.extend(node.children)
    parts = ", ".join(f"{t} x{n}" if n > 1 else t for t, n in sorted(counts.items()))
    where = sdf.path.name if sdf.path is not None else "inline"
    centre = ", ".join(f"{c:g}" for c in sdf.center)
    return (f"analytic SDF '{sdf.name}' ({where}): {sum(counts.values())} nodes ({parts}); "
            f"bound centre ({centre}) radius {sdf.radius:g}")


def _mesh_json(mesh):
    """A mesh file's path, or a built-in shape as the scene names it ({"shape": ..., parameters})."""
    if mesh is None:
        return None
    return str(mesh.path) if mesh.path is not None else {"shape": mesh.shape, **mesh.params}


def _scene_json(scene) -> dict:
    from inshade.scene.description import NetworkSdfRef

    if isinstance(scene.sdf, NetworkSdfRef):
        sdf = {"network": str(scene.sdf.bundle), "prefix": scene.sdf.prefix}
    elif scene.sdf is not None:
        sdf = {"name": scene.sdf.name, "file": str(scene.sdf.path) if scene.sdf.path else None, **scene.sdf.to_dict()}
    else:
        sdf = None
    settings = {s.name: {"type": s.type, "default": s.default, "min": s.min, "max": s.max,
                         "choices": list(s.choices), "binding": s.binding, "target": s.target,
                         "label": s.label, "exposed": s.exposed} for s in scene.settings.values()}
    return {"name": scene.name, "title": scene.title, "path": str(scene.source), "program": scene.program,
            "size": list(scene.size), "sdf": sdf, "mesh": _mesh_json(scene.mesh),
            "settings": settings}


def cmd_info(args) -> int:
    from inshade import bundle as bundle_mod
    from inshade.envelope import analyse, format_findings
    from inshade.scene.description import NetworkSdfRef

    src = _resolve(args.bundle)
    scene, nets = _asset_networks(src)
    if scene is None:
        nets = [(None, None, src)]
    loaded = []
    for role, prefix, path in nets:
        b = bundle_mod.load(path)
        envelope = analyse(b)
        if args.json:   # the description on stdout is JSON: its warnings are said on stderr too
            for line in format_findings(envelope, notes=False):
                if line.startswith("warning:"):
                    log.warning("%s: %s", b.path or b.name, line)
        loaded.append((role, prefix, b, envelope))
    if scene is None:
        _, _, b, envelope = loaded[0]
        if args.json:
            print(json.dumps(_bundle_json(b, envelope), indent=2, sort_keys=True))
        else:
            _describe_bundle(b, envelope)
        return 0
    if args.json:
        print(json.dumps({"scene": _scene_json(scene),
                          "bundles": [{"role": role, "prefix": prefix, "path": str(b.path), **_bundle_json(b, env)}
                                      for role, prefix, b, env in loaded]},
                         indent=2, sort_keys=True))
        return 0
    print(f"{scene.name}: {scene.title}" if scene.title and scene.title != scene.name else scene.name)
    print(f"scene:    {scene.source}")
    print(f"program:  {scene.program}, {scene.size[0]}x{scene.size[1]}")
    if isinstance(scene.sdf, NetworkSdfRef):
        print(f"geometry: network SDF {scene.sdf.bundle.name} (prefix {scene.sdf.prefix}), described below")
    elif scene.sdf is not None:
        print(f"geometry: {_sdf_summary(scene.sdf)}")
    elif scene.mesh is not None:
        print(f"geometry: mesh {scene.mesh.name}")
    if not loaded:
        print("networks: none (nothing trained here; `inshade codegen` has nothing to generate)")
    print(f"settings (`inshade render {scene.name} --set NAME=VALUE`):")
    for row in _setting_rows(scene):
        print(row)
    for role, prefix, b, envelope in loaded:
        print()
        print(f"== {role} (prefix {prefix}): {b.path}")
        _describe_bundle(b, envelope, indent="  ")
    return 0


# render -----------------------------------------------------------------------------------
def cmd_render(args) -> int:
    if args.output == STDOUT:   # a PNG on stdout (no sidecar: there is no file to put it beside)
        with tempfile.TemporaryDirectory() as tmp:
            image, _ = _render(args, str(Path(tmp) / "stdout.png"))
            sys.stdout.buffer.write(Path(image).read_bytes())
            sys.stdout.buffer.flush()
        log.info("wrote a PNG to standard output (no sidecar)")
        return 0
    for p in _render(args, args.output):
        print(f"wrote {p}", file=sys.stderr)
    return 0


def _render(args, output) -> tuple:
    """Render as the options say into ``output`` (an image path; None with --from); the paths written."""
    from inshade.runtime.headless import (IMAGE_SUFFIXES, render_bundle, render_from_sidecar, render_scene,
                                          save_render)

    if output is not None:
        suffix = Path(output).suffix.lower()
        if suffix not in IMAGE_SUFFIXES:
            raise UserError(f"{output}: -o: unknown image type {suffix or '(none)'!r}; use .png or .exr")
        check_output(output)
        check_output(str(output) + ".json", "-o (its .json sidecar)")
    if args.from_ is not None:
        if args.bundle is not None:
            raise UserError("render: give either an ASSET or --from SIDECAR, not both")
        if args.spp is not None:
            raise UserError("render: --from re-renders the spp its sidecar records; drop --spp")
        image, info, record = render_from_sidecar(args.from_)
        out = output
        if out is None:  # shot.png.json -> shot.from.png
            image_path = Path(str(args.from_)[:-5] if str(args.from_).endswith(".json") else args.from_)
            out = image_path.with_name(image_path.stem + ".from" + (image_path.suffix or ".png"))
            check_output(out)
        paths = _save(save_render, image, info, out)
    else:
        if args.bundle is None or output is None:
            raise UserError("render: needs an ASSET and -o IMAGE (or --from SIDECAR)")
        src = _resolve(args.bundle)
        settings = _settings(args)
        from inshade.scene.description import is_scene

        if is_scene(src):
            image, info = render_scene(src, width=args.width, height=args.height, settings=settings,
                                       spp=args.spp or 1)
        else:
            if set(settings) - {"storage", "lut_filter"}:
                raise UserError("render: --set needs a scene (scene.json); a bare bundle has no settings")
            image, info = render_bundle(src, width=args.width, height=args.height,
                                        storage=settings.get("storage", "auto"),
                                        lut_filter=settings.get("lut_filter", "exact"), spp=args.spp or 1)
        paths = _save(save_render, image, info, output)
    return tuple(paths) if isinstance(paths, (list, tuple)) else (paths,)


def cmd_export_web(args) -> int:
    from inshade.web.export import export_web

    page = export_web(_resolve(args.asset), args.output, force=args.force, settings=_settings(args),
                      width=args.width, height=args.height)
    m = page.manifest
    fixed = [s["name"] for s in m["settings"] if "fixed" in s]
    log.info("%s: %d programs, %.1f MB of data; needs %s%s", m["name"], len(page.programs), page.blob.size / 1e6,
             ", ".join(m["requires"]["extensions"]),
             "".join(f", {k} >= {v}" for k, v in m["requires"]["limits"].items()))
    if fixed:
        log.info("fixed in the page (choose with --set): %s", ", ".join(fixed))
    print(f"wrote {args.output}/index.html (serve the folder: python -m http.server -d {args.output})",
          file=sys.stderr)
    return 0


def cmd_export_gltf(args) -> int:
    from inshade.runtime.gltf_export import export_gltf

    done = export_gltf(_resolve(args.asset), args.output, material=args.material, size=args.size,
                       settings=_settings(args), force=args.force, compress=args.compress, textures=args.textures)
    for note in done.notes:
        log.info("%s", note)
    print(f"wrote {done.path} ({done.material} material, {done.primitives} primitive"
          f"{'s' if done.primitives != 1 else ''})", file=sys.stderr)
    return 0


def cmd_serve(args) -> int:
    from inshade.web.browser import serve
    from inshade.web.export import export_web

    with tempfile.TemporaryDirectory(prefix="inshade-web-") as tmp:
        folder = Path(tmp) / "page"
        export_web(_resolve(args.asset), folder, settings=_settings(args))
        try:
            with serve(folder, port=args.port) as url:
                print(f"serving {args.asset} at {url}index.html (Ctrl+C to stop)", flush=True)
                threading.Event().wait()
        except OSError as e:
            raise UserError(f"serve: --port {args.port}: {e.strerror or e}") from None
    return 0


def _save(save_render, image, info, out):
    try:
        return save_render(image, info, out)
    except OSError as e:
        raise _write_error(out, e) from None


def _settings(args) -> dict:
    """Scene settings the user gave: --storage, --lut-filter and --set NAME=VALUE (VALUE parsed
    as JSON when it is JSON, else kept as a string); the scene's defaults fill in the rest."""
    settings = {}
    if args.storage is not None:
        settings["storage"] = args.storage
    if args.lut_filter is not None:
        settings["lut_filter"] = args.lut_filter
    for item in args.set or []:
        name, sep, text = item.partition("=")
        if not sep or not name:
            raise UserError(f"{args.command}: --set expects NAME=VALUE, got {item!r}")
        if name in settings:
            raise UserError(f"{args.command}: --set {name}: given more than once (or also by its own option)")
        try:
            settings[name] = json.loads(text)
        except ValueError:
            settings[name] = text
    return settings


# view -------------------------------------------------------------------------------------
def cmd_view(args) -> int:
    import imgui_bundle  # noqa: F401  (a missing view extra is said before the display is looked for)

    from inshade.viewer.app import NoDisplayError, ViewerApp
    size = (args.width, args.height)
    settings = {"storage": args.storage} if args.storage else None
    try:
        app = ViewerApp(_resolve(args.asset) if args.asset is not None else None, size=size, settings=settings, trained_root=args.trained)
    except NoDisplayError as e:
        raise UserError(str(e)) from None
    if args.frames:
        app.step(args.frames)
        if args.screenshot:
            for k, p in app.screenshot(args.screenshot).items():
                print(f"wrote {p}", file=sys.stderr)
        app.close()
        return 0
    app.run()
    return 0


# doctor -----------------------------------------------------------------------------------
def cmd_doctor(args) -> int:
    from inshade.runtime import context

    backend, device = context.resolve()
    devices = context.egl_device_list()
    try:
        info = context.gl_info(context.shared_context())
    except context.GLContextError:
        if not args.json:   # what can be said without a context, then the error line
            _print_egl_devices(devices, backend, device)
            if backend == "egl":
                print("hint: EGL cannot create a context here; Mesa's off-screen library may still work: "
                      "apt-get install libosmesa6, then `inshade --gl-backend osmesa doctor`")
        raise
    info["egl_devices"] = [d.describe() for d in devices]
    info["gl_backend"] = backend
    info["egl_device"] = (device or 0) if backend == "egl" else None
    if args.json:
        print(json.dumps(info, indent=2, sort_keys=True))
        return 0
    width = max(len(k) for k in info)
    for k, v in info.items():
        print(f"{k:<{width}}  {v}")
    _print_egl_devices(devices, backend, device)
    if info.get("software"):
        print("note: this is a software rasteriser (CPU); timings are not GPU timings")
    return 0


def _print_egl_devices(devices, backend: str, device) -> None:
    """The EGL device list with the one in use marked, and the NVIDIA hints when none is a GPU."""
    from inshade.runtime.context import nvidia_hints

    used = (device or 0) if backend == "egl" else None
    print(f"EGL devices ({len(devices)}; --gl-device N / INSHADE_EGL_DEVICE=N picks one):")
    for d in devices:
        mark = "*" if d.index == used else " "
        print(f"  {mark} {d.index}: {d.describe()}{'  [software]' if d.software else ''}")
    if backend != "egl":
        print(f"  (not used: the {backend} backend renders)")
    if not any(not d.software for d in devices):
        print("note: EGL sees no GPU. An NVIDIA GPU needs the driver's EGL library registered with glvnd "
              "(libnvidia-gl-*, and in a container NVIDIA_DRIVER_CAPABILITIES=graphics,compute,utility); "
              "docs/gpu.md has the steps. Checked here:")
        for hint in nvidia_hints():
            print(f"  - {hint}")


# bench / train mount modules that bring their own arguments -------------------------------
def _mount(sub, name: str, table: dict, help_: str) -> None:
    p = sub.add_parser(name, help=help_, description=help_)
    inner = p.add_subparsers(dest="target", metavar="NAME", required=True)
    for key, (module, text) in table.items():
        q = inner.add_parser(key, help=text, description=text)
        q.set_defaults(module=module)
        # arguments are parsed by the module itself (its deps are optional extras)
        q.add_argument("rest", nargs=argparse.REMAINDER, help="options of this command (try --help)")
    p.set_defaults(func=_run_module)


def _run_module(args) -> int:
    return importlib.import_module(args.module).main(args.rest)


def build_parser() -> argparse.ArgumentParser:
    from inshade.codegen import FILTERS, STORAGE_MODES, TARGETS

    ap = ArgumentParser(prog="inshade", description="Run PyTorch-trained networks in OpenGL shaders. "
                        "An ASSET is a folder (scene.json and/or a bundle) or the name of a shipped one "
                        "(looked up in $INSHADE_ASSETS, then trained/), e.g. `inshade render prt_creature -o x.png`.")
    ap.add_argument("-q", "--quiet", action="store_true", help="only errors on stderr")
    _gl_options(ap, None)
    sub = ap.add_subparsers(dest="command", metavar="COMMAND", required=True)

    p = sub.add_parser("codegen", help="bundle -> GLSL (prints the plan report)",
                       description="Generate the GLSL function of a bundle; prints the plan report. With -o, "
                                   "writes the flattened GLSL, a .json manifest and the resources "
                                   "(.resources.safetensors) the code binds. Given an asset, generates the "
                                   "network its scene.json names; an asset with several networks (e.g. a PRT "
                                   "transfer network over a network SDF) needs --network PREFIX to pick one.")
    p.add_argument("bundle",
                   help="bundle folder (bundle.json + weights.safetensors), or an asset folder / shipped asset name")
    p.add_argument("--network", metavar="PREFIX",
                   help="the asset's network to generate, by its prefix (needed when it has several); 'all' "
                        "generates each (-o net.glsl writes net.PREFIX.glsl per network)")
    p.add_argument("--program", action="store_true",
                   help="write the asset's whole pass instead: its fragment stage with every include resolved "
                        "(-o PASS.frag), the vertex stage beside it, and a .json of the uniforms and resources to bind")
    p.add_argument("-o", "--output", help="GLSL file to write (- : the GLSL alone on standard output, the plan on "
                                          "stderr; only for code that binds no resources)")
    p.add_argument("--storage", choices=STORAGE_MODES, default="auto", help="dense weight placement")
    p.add_argument("--target", choices=TARGETS, default="330", help="GLSL target")
    p.add_argument("--lut-filter", choices=FILTERS, default="exact", help="lookup array filtering path")
    p.add_argument("--texture-format", choices=("f4", "f2"), default="f4", help="weight texture texel format")
    p.add_argument("--calls", type=_count, default=1, metavar="N",
                   help="how many times your shader evaluates the function per pixel (e.g. a march's steps): on "
                        "a driver that caps a pixel's loop iterations (llvmpipe) the dense loops unroll to fit")
    p.add_argument("--prefix", help="name prefix of the generated symbols (default: the network's prefix in "
                                    "the asset's scene.json, else net)")
    p.add_argument("--no-gl", action="store_true", help="plan against GL 3.3's minimum limits instead of this "
                                                          "machine's (no GL context is made)")
    p.set_defaults(func=cmd_codegen)

    from inshade.convert.commands import add_parsers as add_convert_parsers

    add_convert_parsers(sub)

    p = sub.add_parser("info", help="describe a bundle or an asset",
                       description="Validate and describe a bundle, or an asset: its scene, the --set settings "
                                   "it takes (types, ranges, defaults) and every bundle it uses. Long training "
                                   "histories are summarised; --json has everything.")
    p.add_argument("bundle",
                   help="bundle folder, asset folder (scene.json), scene.json or shipped asset name")
    p.add_argument("--json", action="store_true", help="machine-readable output (everything)")
    p.set_defaults(func=cmd_info)

    p = sub.add_parser("render", help="render a bundle headless to PNG/EXR + JSON sidecar",
                       description="Render an asset headless (EGL). .png: exposure applied, then the scene's tone mapper "
                                   "(--set tonemap=none|reinhard|pbr_neutral; none unless the scene says otherwise, "
                                   "e.g. pbr_neutral for glTF files; none clips values above 1), sRGB-encoded 8-bit; "
                                   ".exr: linear float32, exposure-scaled, never tone mapped; "
                                   "a JSON sidecar records the settings, bundle digest and GL renderer.")
    p.add_argument("bundle", nargs="?", metavar="ASSET",
                   help="asset folder (scene.json, or a bundle with a 'render' field), scene.json, bundle, "
                        "or the name of a shipped asset (e.g. prt_creature); `inshade info ASSET` lists its settings")
    p.add_argument("-o", "--output", help="image path (.png or .exr; - : a PNG on standard output, no sidecar); "
                                          "with --from defaults to <shot>.from.png")
    p.add_argument("--from", dest="from_", metavar="SIDECAR",
                   help="re-render exactly what a screenshot's JSON sidecar (shot.png.json) describes")
    p.add_argument("--width", type=_size)
    p.add_argument("--height", type=_size)
    p.add_argument("--storage", choices=STORAGE_MODES, help="weight storage (default: the scene's, else auto)")
    p.add_argument("--lut-filter", choices=FILTERS, help="lookup array path (default: the scene's, else exact)")
    p.add_argument("--set", action="append", metavar="NAME=VALUE",
                   help="a scene setting, e.g. --set sky=sunset --set env_rotation=90 (repeatable)")
    p.add_argument("--spp", type=_count, metavar="N",
                   help="samples per pixel averaged by a stochastic (accumulating) program (default 1)")
    p.set_defaults(func=cmd_render)

    p = sub.add_parser("export-web", help="an asset as a static WebGL2 page (index.html + inshade.js + data)",
                       description="Write ASSET as a static folder that any file server shows (python -m http.server): "
                                   "index.html (the viewer: orbit / zoom / pan, the settings, split and error views "
                                   "where the asset has a reference, progressive accumulation, frame time), "
                                   "evaluate.html (the network on a test batch), inshade.js, the programs as GLSL "
                                   "ES 3.00 and the data as data.bin + manifest.json. Planned against WebGL2's "
                                   "guaranteed limits; an asset that cannot fit is refused naming the limit. "
                                   "Settings compiled into the program or feeding per-frame work are fixed in the "
                                   "page: choose them with --set.")
    p.add_argument("asset", metavar="ASSET", help="asset folder, scene.json, bundle, or a shipped asset's name")
    p.add_argument("-o", "--output", required=True, metavar="DIR", help="the folder to write (new or empty)")
    p.add_argument("--width", type=_size, help="canvas width (default: the scene's)")
    p.add_argument("--height", type=_size, help="canvas height (default: the scene's)")
    p.add_argument("--storage", choices=STORAGE_MODES, help="weight storage (default: the scene's, else auto)")
    p.add_argument("--lut-filter", choices=FILTERS, help="lookup array path (default: the scene's, else exact)")
    p.add_argument("--set", action="append", metavar="NAME=VALUE", help="a scene setting (repeatable)")
    p.add_argument("--force", action="store_true", help="replace what the folder holds")
    p.set_defaults(func=cmd_export_web)

    p = sub.add_parser("export-gltf", help="an asset's mesh and material as a glTF 2.0 binary (.glb)",
                       description="Write ASSET's mesh (normals, uv, tangents; a primitive per material) with its "
                                   "material as one .glb: the material its network decodes, baked into the mesh's "
                                   "uv space by the GL runtime (--material decoded), or the glTF material the asset "
                                   "was made from (--material reference); auto picks decoded where the asset's "
                                   "program can bake it.")
    p.add_argument("asset", metavar="ASSET", help="asset folder, scene.json, a .glb/.gltf, or a shipped asset's name")
    p.add_argument("-o", "--output", required=True, metavar="OUT.glb", help="the file to write")
    p.add_argument("--material", choices=("auto", "decoded", "reference"), default="auto",
                   help="which material to write (default auto)")
    p.add_argument("--size", type=_size, default=512, help="side of the baked textures in texels (default 512)")
    p.add_argument("--compress", choices=("none", "draco", "meshopt"), default="none",
                   help="the mesh as it is (default), or compressed: draco (KHR_draco_mesh_compression, "
                        "quantized) or meshopt (EXT_meshopt_compression, lossless); both need the gltf extra")
    p.add_argument("--textures", choices=("png", "ktx2"), default="png",
                   help="texture images: png (default), or ktx2 (KHR_texture_basisu, UASTC; needs the gltf extra)")
    p.add_argument("--set", action="append", metavar="NAME=VALUE", help="a scene setting (repeatable)")
    p.add_argument("--storage", choices=STORAGE_MODES, help=argparse.SUPPRESS)
    p.add_argument("--lut-filter", choices=FILTERS, help=argparse.SUPPRESS)
    p.add_argument("--force", action="store_true", help="replace OUT.glb if it exists")
    p.set_defaults(func=cmd_export_gltf)

    p = sub.add_parser("serve", help="export ASSET to a temporary page and serve it on localhost",
                       description="Export ASSET as export-web does, into a temporary folder, and serve it on "
                                   "localhost until Ctrl+C; prints the address to open.")
    p.add_argument("asset", metavar="ASSET", help="asset folder, scene.json, bundle, or a shipped asset's name")
    p.add_argument("--port", type=int, default=8000, help="port (default 8000; 0: any free port)")
    p.add_argument("--set", action="append", metavar="NAME=VALUE", help="a scene setting (repeatable)")
    p.add_argument("--storage", choices=STORAGE_MODES, help=argparse.SUPPRESS)
    p.add_argument("--lut-filter", choices=FILTERS, help=argparse.SUPPRESS)
    p.set_defaults(func=cmd_serve)

    p = sub.add_parser("view", help="interactive viewer window (glfw + imgui-bundle)",
                       description="Open ASSET (a trained/ folder, scene.json or bundle) in a window, with a "
                                   "scene picker listing trained/. Needs a display: on a headless machine use "
                                   "xvfb-run. Keys: 1-5 display modes, T neural/reference, F frame, Home reset, "
                                   "F12 screenshot, Esc quit.")
    p.add_argument("asset", nargs="?", help="asset folder or shipped asset name (default: none: choose one in the scene list)")
    p.add_argument("--width", type=_size, default=1280)
    p.add_argument("--height", type=_size, default=800)
    p.add_argument("--storage", choices=STORAGE_MODES, help="override the scene's weight storage")
    p.add_argument("--trained", help="folder the scene picker lists (default: the shipped trained/)")
    p.add_argument("--frames", type=int, help="run N frames and exit (scripts, smoke tests)")
    p.add_argument("--screenshot", help="with --frames: write this screenshot (PNG + EXR + sidecar) at the end")
    p.set_defaults(func=cmd_view)

    p = sub.add_parser("doctor", help="GL vendor/renderer/version and the limits codegen uses",
                       description="Report the OpenGL context inshade gets here: vendor, renderer, version, "
                                   "limits that matter for codegen, software or not, the backend, and the EGL "
                                   "devices with the one in use marked. When EGL sees no GPU it says what to "
                                   "check (NVIDIA driver, NVIDIA_DRIVER_CAPABILITIES=graphics, glvnd); when "
                                   "EGL cannot start at all it suggests --gl-backend osmesa.")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_doctor)

    for alias, (command, name) in aliases().items():
        p = sub.add_parser(alias, help=f"same as `inshade {command} {name}`",
                           description=f"Same as `inshade {command} {name}`; try `inshade {command} {name} --help`.")
        p.add_argument("rest", nargs=argparse.REMAINDER, help="its options")
        p.set_defaults(func=_run_module, module=(trainers() if command == "train" else benches())[name][0])

    _mount(sub, "bench", benches(), "benchmarks (write JSON + markdown + plot)")
    _mount(sub, "train", trainers(), "build trained/ assets")
    for name, p in sub.choices.items():   # -q also after the command (`inshade render x -q ...`);
        if name not in ("bench", "train", *aliases()):   # SUPPRESS keeps a -q given before it
            p.add_argument("-q", "--quiet", action="store_true", default=argparse.SUPPRESS,
                           help="only errors on stderr")
        if name in GL_COMMANDS:
            _gl_options(p, argparse.SUPPRESS)
    return ap


# GL backend and device: global options (before the command, or after it for the commands that
# make a GL context; bench and train take them anywhere among their own options)
GL_COMMANDS = ("codegen", "render", "view", "doctor", "convert", "eval")
GL_OPTIONS = ("--gl-backend", "--gl-device")


_DEVICE_INDEX = "expected an EGL device index (0, 1, ...)"
_device_index = _int_at_least(0, _DEVICE_INDEX, _DEVICE_INDEX)


def _gl_options(p, default) -> None:
    from inshade.runtime.context import BACKENDS

    p.add_argument("--gl-backend", choices=BACKENDS, default=default,
                   help="headless OpenGL: egl (default; GPUs and Mesa) or osmesa (Mesa's off-screen CPU "
                        "library, for where EGL cannot start); env INSHADE_GL_BACKEND")
    p.add_argument("--gl-device", type=_device_index, metavar="N", default=default,
                   help="EGL device to render on (`inshade doctor` lists them); env INSHADE_EGL_DEVICE")


def _split_gl_options(argv: list[str]) -> tuple[list[str], list[str]]:
    """(--gl-backend/--gl-device options, the other arguments) of a bench/train command line;
    a `--` ends the search."""
    gl, rest, i = [], [], 0
    while i < len(argv):
        arg = argv[i]
        if arg == "--":
            rest += argv[i:]
            break
        if arg in GL_OPTIONS:
            gl += argv[i:i + 2]
            i += 2
            continue
        (gl if arg.split("=", 1)[0] in GL_OPTIONS else rest).append(arg)
        i += 1
    return gl, rest


def _apply_gl_options(args) -> None:
    """Check the GL flags and make them the process's choice (context.select)."""
    backend, device = getattr(args, "gl_backend", None), getattr(args, "gl_device", None)
    if backend is None and device is None:
        return
    if getattr(args, "command", None) == "view":
        raise UserError("view: --gl-backend/--gl-device choose the headless context; a window renders on its "
                        "display's GPU (on a hybrid laptop: __NV_PRIME_RENDER_OFFLOAD=1 "
                        "__GLX_VENDOR_LIBRARY_NAME=nvidia inshade view)")
    from inshade.runtime.context import select

    select(backend, device)


def main(argv=None) -> int:
    """Run a command; Ctrl+C ends it quietly with status 130, a closed output pipe (`| head`)
    with status 141, neither with a traceback."""
    try:
        try:
            return _main(argv)
        finally:
            if sys.stdout is not None:
                sys.stdout.flush()   # a closed pipe shows here, where it is handled below
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        # Python's recipe: point stdout at devnull so the flush at exit does not fail again
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except (OSError, ValueError, AttributeError):   # a stdout without a file descriptor
            pass
        return 141


def _main(argv) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = build_parser()
    # `inshade bench mlp ...` / `inshade train X ...`: the module parses its own options
    # (so its --help is its own), after the global ones.
    lead = _leading_options(argv)
    rest = argv[len(lead):]
    if rest and rest[0] in aliases():
        rest = [*aliases()[rest[0]], *rest[1:]]
    tables = {"train": trainers, "bench": benches}
    if len(rest) >= 2 and rest[0] in tables and rest[1] in tables[rest[0]]():
        # the module parses its own options (and --help); the global ones are taken out first
        gl, module_rest = _split_gl_options(rest[2:])
        args = _global_parser().parse_args([*lead, *gl])
        args.module, args.rest, args.func = tables[rest[0]]()[rest[1]][0], module_rest, _run_module
    else:
        args = ap.parse_args(argv)
    logging.basicConfig(level=logging.WARNING if args.quiet else logging.INFO,
                        format="inshade: %(message)s", stream=sys.stderr)
    logging.getLogger("OpenGL").setLevel(logging.WARNING)   # no "No OpenGL_accelerate module loaded"
    try:
        _apply_gl_options(args)
        return int(args.func(args) or 0)
    except _user_errors() as e:
        print(f"inshade: error: {_one_line(str(e))}", file=sys.stderr)
        return 2
    except ModuleNotFoundError as e:   # an optional extra that is not installed (a runtime-only install)
        if (e.name or "inshade").startswith("inshade"):
            raise
        from inshade.extras import missing_line

        command = " ".join(rest[:2]) if rest and rest[0] in tables else getattr(args, "command", None)
        print(f"inshade: error: {missing_line(e.name, command)}", file=sys.stderr)
        return 2
    except BrokenPipeError:   # stdout closed (`| head`): main() ends quietly
        raise
    except OSError as e:   # an input that cannot be read (permissions, a folder for a file, ...)
        where = f"{e.filename}: " if e.filename else ""
        print(f"inshade: error: {where}{_one_line(str(e.strerror or e))}", file=sys.stderr)
        return 2


def _global_parser() -> argparse.ArgumentParser:
    """The options every command takes (for bench/train, whose modules parse the rest)."""
    ap = ArgumentParser(prog="inshade", add_help=False)
    ap.add_argument("-q", "--quiet", action="store_true")
    _gl_options(ap, None)
    return ap


def _leading_options(argv: list[str]) -> list[str]:
    """The global options before the command: -q, --gl-backend B, --gl-device N (or OPTION=VALUE)."""
    i = 0
    while i < len(argv):
        name = argv[i].split("=", 1)[0]
        if argv[i] in ("-q", "--quiet") or name != argv[i] and name in GL_OPTIONS:
            i += 1
        elif argv[i] in GL_OPTIONS:
            i += 2
        else:
            break
    return argv[:i]


def _interrupted(signum, frame) -> None:
    """Ctrl+C in the `inshade` executable: remove unfinished outputs and leave at once, status 130.
    Unwinding instead would release GL objects while the driver's threads may still be drawing
    them, which crashes llvmpipe now and then (SIGSEGV)."""
    from inshade.files import remove_temporaries
    from inshade.progress import stop_watchers

    stop_watchers()
    remove_temporaries()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError, AttributeError):
            pass
    os._exit(130)


def entry() -> None:
    """The `inshade` executable (``main`` in-process still turns Ctrl+C into status 130)."""
    signal.signal(signal.SIGINT, _interrupted)
    sys.exit(main())


if __name__ == "__main__":
    entry()
