"""`inshade codegen`: a bundle's (or an asset's network's) GLSL function, its plan report, and with
-o the GLSL, its manifest and the resources it binds; --program: an asset's whole pass."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from .common import STDOUT, UserError, asset_networks, check_output, count, resolve, write_error


def add_parser(sub) -> None:
    from inshade.codegen import FILTERS, STORAGE_MODES, TARGETS
    from inshade.components.dense.spec import ARITHMETIC
    from inshade.quantize import PRECISIONS
    from inshade.engines import ENGINES

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
    p.add_argument("--force", action="store_true", help="replace the files -o would write if they exist")
    p.add_argument("--storage", choices=STORAGE_MODES, default="auto", help="dense weight placement")
    p.add_argument("--target", choices=(*TARGETS, "shadertoy"), default="330",
                   help="shading language: GLSL 330 / 450 / es300 (OpenGL), vulkan (GLSL 4.50 for Vulkan), wgsl "
                        "(WebGPU), hlsl (D3D11/12, Unity, Unreal), slang; beyond OpenGL, planned against that API's "
                        "guaranteed limits. shadertoy: a uv -> colour network as one Shadertoy Image pass to paste "
                        "(mainImage, the weights as literals)")
    p.add_argument("--engine", choices=ENGINES,
                   help="with --target hlsl: the network as a game engine's node takes it: unity (a Shader Graph "
                        "Custom Function file, File mode) or unreal (a Custom node's Code); the weights as literals, "
                        "or with --storage texture (and any lookup tables) as EXR / PNG images beside -o with a "
                        "README of their import settings")
    p.add_argument("--check", action="store_true",
                   help="run the generated code on this machine's driver for the target (OpenGL; wgpu on Vulkan for "
                        "wgsl / vulkan / hlsl / slang) against the bundle's torch twin and print "
                        "max |code - source| under the 1e-5 rule (exit 1 when it fails)")
    p.add_argument("--lut-filter", choices=FILTERS, default="exact", help="lookup array filtering path")
    p.add_argument("--texture-format", choices=("f4", "f2"), default="f4", help="weight texture texel format")
    p.add_argument("--precision", choices=PRECISIONS,
                   help="store the dense weights at this precision (default: the bundle's own): f16 (half the "
                        "bytes of a weight texture) or i8 (a quarter: int8 codes times a scale per output row); "
                        "--check then holds the code to the quantized network's twin and prints the "
                        "quantization's own error beside it")
    p.add_argument("--arithmetic", choices=ARITHMETIC, default="f32",
                   help="what the dense layers compute in: f32, f16 (float16 products and sums) or f16_acc32 "
                        "(float16 block products, float32 sums); f16 needs --target vulkan "
                        "(GL_EXT_shader_explicit_arithmetic_types_float16) or wgsl (enable f16) and float16 weights "
                        "(--precision f16, the default with it); --check then holds the code to the float16 "
                        "envelope (docs/precision.md)")
    p.add_argument("--calls", type=count, default=1, metavar="N",
                   help="how many times your shader evaluates the function per pixel (e.g. a march's steps): on "
                        "a driver that caps a pixel's loop iterations (llvmpipe) the dense loops unroll to fit")
    p.add_argument("--prefix", help="name prefix of the generated symbols (default: the network's prefix in "
                                    "the asset's scene.json, else net)")
    p.add_argument("--no-gl", action="store_true", help="plan against GL 3.3's minimum limits instead of this "
                                                          "machine's (no GL context is made)")
    p.add_argument("--limit", action="append", default=[], metavar="NAME=VALUE", type=_limit,
                   help="plan with your device's value of a limit, by its GL name (e.g. GL_MAX_TEXTURE_SIZE=16384, "
                        "GL_MAX_FRAGMENT_SHADER_STORAGE_BLOCKS=16), over the target's or this machine's; repeatable")
    p.set_defaults(func=cmd_codegen)


def _limit(text: str) -> tuple[str, int]:
    from inshade.codegen import GL33_MINIMUMS
    from inshade.web.shadertoy import PASS_CHARS_LIMIT

    names = (*GL33_MINIMUMS, PASS_CHARS_LIMIT)
    name, sep, value = text.partition("=")
    if not sep or name not in names or not value.strip().isdigit():
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE with NAME one of {', '.join(names)} and an "
                                         f"integer VALUE, got {text!r}")
    return name, int(value)


def cmd_codegen(args) -> int:
    from inshade import bundle as bundle_mod

    if args.output not in (None, STDOUT):
        check_output(args.output)
        if args.network != "all":
            _refuse_existing(args.output, args.force)
    if Path(args.bundle).suffix.lower() == ".onnx":   # converted in memory (inshade convert writes it)
        from inshade.convert.onnx_model import to_bundle

        scene, b = None, to_bundle(args.bundle)[0]
        if args.network is not None:
            raise UserError(f"{args.bundle}: --network picks a network of an asset; this is an ONNX file")
        return _codegen(args, b, args.prefix, args.output)
    src = resolve(args.bundle)
    scene, nets = asset_networks(src)
    prefix = args.prefix
    if args.program:
        return _codegen_program(args, src)
    if args.target == "shadertoy" and scene is not None and scene.program == "passes/sdf_diffuse.frag":
        return _shadertoy_sdf(args, src)
    if args.network == "all":
        if scene is None or not nets:
            raise UserError(f"{src}: --network all: needs an asset with networks (a folder with scene.json)")
        if args.output == STDOUT and len(nets) > 1:
            raise UserError(f"-o -: {len(nets)} networks would share standard output; write to a file (-o net.glsl "
                            "becomes net.PREFIX.glsl per network)")
        outs = [args.output if args.output in (None, STDOUT) else str(
            Path(args.output).with_name(f"{Path(args.output).stem}.{net_prefix}{Path(args.output).suffix}"))
            for _, net_prefix, _ in nets]
        for out in outs:   # all refused before any is written
            _refuse_existing(out, args.force)
        for (role, net_prefix, bpath), out in zip(nets, outs):
            print(f"== network {net_prefix} ({role}, {Path(bpath).name})")
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


def _refuse_existing(output, force: bool) -> None:
    if output not in (None, STDOUT) and Path(output).is_file() and not force:
        raise UserError(f"{output}: -o: exists; add --force to replace it")


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
    ``extra`` {path: text or bytes}: all together or none."""
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
                tmp.write_bytes(body) if isinstance(body, bytes) else tmp.write_text(body)
            if tensors:
                save_file(tensors, str(temps[-1]))
    except OSError as e:
        raise write_error(out, e) from None
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
    """The network's code for --target, its plan, --check, and with -o the files."""
    from inshade.codegen import generate
    from inshade.codegen.targets import target as find_target
    from inshade.shaders import flatten

    if args.target == "shadertoy":
        return _shadertoy(args, b, output)
    if args.engine is not None:
        return _engine(args, b, output)
    fp32 = b
    precision = args.precision
    if precision is None and args.arithmetic != "f32":
        precision = "f16"
        print(f"arithmetic {args.arithmetic}: the dense weights at precision f16 (float16 values)", file=sys.stderr)
    if precision is not None:
        from inshade.quantize import quantized

        b = quantized(b, precision)
    opengl = find_target(args.target).opengl
    if args.no_gl or not opengl:   # beyond OpenGL: the target API's own limits (codegen/targets.py)
        limits = {}
    else:   # plan against this machine's limits when it can make a context
        from inshade.runtime.context import machine_limits

        limits = machine_limits()
    limits = {**limits, **dict(args.limit)}
    gen = generate(b, storage=args.storage, target=args.target, prefix=prefix or "net",
                   lut_filter=args.lut_filter, texture_format=args.texture_format, limits=limits, calls=args.calls,
                   arithmetic=args.arithmetic)
    if output == STDOUT:   # the GLSL alone on stdout; the plan goes to stderr
        if gen.resources:
            raise UserError(f"-o -: this GLSL binds {len(gen.resources)} resources "
                            f"({', '.join(r.name for r in gen.resources)}) that standard output cannot carry; "
                            "write to a file (-o net.glsl) or use --storage inline")
        print(gen.plan.report(), file=sys.stderr)
        sys.stdout.write(flatten("network", chunks={"network": gen.chunk}) if opengl else gen.chunk)
        return 0
    print(gen.plan.report())
    if opengl:
        _say_compile_cost(limits, gen)
    if args.check and not _check(b, gen, args.target, fp32, args.arithmetic):
        return 1
    if output is None:
        return 0
    out = Path(output)
    entries, tensors = _resource_manifest(gen.resources)
    manifest = {"bundle": str(b.path if b.path is not None else args.bundle), "bundle_digest": b.digest(),
                "function": gen.function, "in_dim": gen.in_dim, "out_dim": gen.out_dim, "target": args.target,
                "plan": gen.plan.to_dict(), "resources": entries}
    # the GLSL, its manifest and its resources appear together or not at all
    _write_group(out, flatten("network", chunks={"network": gen.chunk}) if opengl else gen.chunk, manifest, tensors)
    print(f"wrote {out} ({len(gen.resources)} resources)", file=sys.stderr)
    return 0


def _say_compile_cost(limits: dict, gen) -> None:
    """On a software driver, what the first draw's JIT will take, and a warning past a few seconds."""
    import logging

    from inshade.progress import format_seconds
    from inshade.runtime.compile_cost import SLOW_COMPILE_S, first_draw_estimate, inline_flops

    seconds = first_draw_estimate(limits, "", [gen])
    if seconds is None or not inline_flops([gen]):
        return
    what = (f"~{format_seconds(seconds)} at the first draw on {limits.get('renderer', 'this driver')} "
            f"(JIT of {inline_flops([gen])} inlined FLOPs)")
    print(f"compile: {what}")
    if seconds >= SLOW_COMPILE_S:
        logging.getLogger("inshade").warning("this program compiles %s; --storage texture compiles in seconds "
                                             "and runs slower", what)


def _span(b):
    """The box --check draws its rows from: [-1, 1] on every input lane."""
    import numpy as np

    return np.stack([np.full(b.in_dim, -1.0), np.full(b.in_dim, 1.0)]).astype(np.float32)


def _check(b, gen, target: str, fp32=None, arithmetic: str = "f32") -> bool:
    """--check: the generated code on its target's driver against the bundle's torch twin (under the
    float16 envelope where the arithmetic is float16); a bundle quantized here (``fp32``: the one it came
    from) has its twin's distance from the fp32 one printed too."""
    from inshade.convert.check import check, check_inputs, per_input
    from inshade.convert.half_envelope import check_half
    from inshade.convert.precision import quantization
    from inshade.models import GraphModule
    from inshade.quantize import QUANTIZED_TYPES

    x = check_inputs(_span(b))
    if arithmetic != "f32":
        result = check_half(b, gen, x, target, arithmetic)
    else:
        result = check(GraphModule.from_bundle(b), b, x, generated=gen, target=target)
    print(f"{result.line()} ({result.rows} rows, {result.gl_renderer})")
    if fp32 is not None and fp32 is not b:
        precision = ", ".join(sorted({n.params["precision"] for n in b.nodes if n.type in QUANTIZED_TYPES}))
        print(quantization(GraphModule.from_bundle(fp32), b, fp32, per_input(b, x), precision, "fp32 twin").line())
    return result.ok


def _pasted(args, b, output, report: str, text: str, check, manifest: dict, extra=None) -> int:
    """Code to paste into another tool: its report, --check (``check()`` gives (lines, ok)), and with -o
    the text and its manifest (-o -: the text alone on standard output); ``extra(out)``: the files that go
    beside it ({path: text or bytes}), which need -o."""
    if extra is not None and output == STDOUT:
        raise UserError("-o -: this code comes with files beside it; -o names the file to write")
    if output == STDOUT:
        print(report, file=sys.stderr)
        sys.stdout.write(text)
        return 0
    print(report)
    if args.check:
        lines, ok = check()
        print("\n".join(lines))
        if not ok:
            return 1
    if output is None:
        return 0
    if b is not None:
        manifest = {"bundle": str(b.path if b.path is not None else args.bundle), "bundle_digest": b.digest(),
                    **manifest}
    files = extra(Path(output)) if extra is not None else {}
    for path in files:
        _refuse_existing(path, args.force)
    _write_group(Path(output), text, manifest, {}, files)
    for path in [output, *files]:
        print(f"wrote {path}", file=sys.stderr)
    return 0


def _shadertoy(args, b, output) -> int:
    """--target shadertoy: the pass to paste, its report, --check run as Shadertoy runs it."""
    from inshade.models import GraphModule
    from inshade.web.shadertoy import check_pass, image_pass

    if args.storage not in ("auto", "inline"):
        raise UserError(f"--target shadertoy: a pasted pass holds its weights as literals; --storage {args.storage} "
                        "needs resources Shadertoy cannot bind (use --target es300)")
    p = image_pass(b, limits=dict(args.limit))

    def check():
        result = check_pass(p, GraphModule.from_bundle(b), b)
        return result.lines(), result.ok

    return _pasted(args, b, output, p.report(), p.text, check,
                   {"target": "shadertoy", "output": p.output, "lanes": list(p.lanes), "srgb": p.srgb,
                    "characters": len(p.text), "weights": p.weights})


def _shadertoy_sdf(args, src) -> int:
    """--target shadertoy of an SDF scene: the pass sphere tracing it, --check against inshade render."""
    from inshade.bundle import load
    from inshade.scene.description import NetworkSdfRef, load_scene
    from inshade.web.shadertoy import check_sdf_pass, sdf_pass

    p = sdf_pass(src, limits=dict(args.limit))

    def check():
        result = check_sdf_pass(p, src)
        return result.lines(), result.ok

    scene = load_scene(src)
    b = load(scene.sdf.bundle) if isinstance(scene.sdf, NetworkSdfRef) else None
    report = f"shadertoy image pass: {len(p.text)} characters, {scene.name} sphere traced from its orbit camera"
    manifest = {"target": "shadertoy", "scene": str(src), "kind": "sdf", "characters": len(p.text),
                "weights": p.weights}
    return _pasted(args, b, args.output, report, p.text, check, manifest)


def _engine(args, b, output) -> int:
    """--engine: the network as the engine's node takes it, its setup, --check through the HLSL driver."""
    from inshade.convert.check import check_inputs
    from inshade.engines import check_drop_in, drop_in, readme
    from inshade.engines.textures import image_bytes
    from inshade.models import GraphModule

    if args.target != "hlsl":
        raise UserError(f"--engine {args.engine}: takes --target hlsl (the engines' shading language), "
                        f"not --target {args.target}")
    if args.storage not in ("auto", "inline", "texture"):
        raise UserError(f"--engine {args.engine}: the drop-in holds its weights as literals or textures; --storage "
                        f"{args.storage} needs blocks bound by your own code (use --target hlsl without --engine)")
    # by default named after the bundle: several share a material
    d = drop_in(b, args.engine, args.prefix, "texture" if args.storage == "texture" else "inline", args.lut_filter)

    def check():
        result = check_drop_in(d, GraphModule.from_bundle(b), b, check_inputs(_span(b)))
        return [f"{result.line()} ({result.rows} rows, {result.gl_renderer})"], result.ok

    def images(out: Path) -> dict:
        files = {out.with_name(f.file): image_bytes(f, pixels) for f, pixels in d.images}
        return {**files, out.with_name(out.stem + ".README.md"): readme(d, out.name)}

    return _pasted(args, b, output, d.report(), d.text, check,
                   {"target": "hlsl", "engine": args.engine, "function": d.generated.prefix, "node": d.node,
                    "inputs": [[p.name, p.dim] for p in d.inputs], "outputs": [[p.name, p.dim] for p in d.outputs],
                    "textures": [{"name": f.name, "file": f.file, "format": f.format, "size": [f.width, f.height],
                                  "filter": "linear" if f.filtered else "nearest", "wrap": f.wrap}
                                 for f, _ in d.images]},
                   images if d.images else None)
