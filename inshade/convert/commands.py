"""The command-line side of the ways in: ``inshade convert`` (ONNX or tiny-cuda-nn -> bundle,
``--ops``) and ``inshade eval`` (a bundle's GLSL on a batch from the shell). Parsers only at
import: torch, onnx and GL load when a command runs."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

SOURCES = {".onnx": "ONNX", ".json": "tiny-cuda-nn"}   # by the MODEL file's suffix
TCNN_PARTS = ("  encodings: Grid, HashGrid, DenseGrid (Hash and Dense storage, 2D and 3D, Linear), Identity,",
              "  Frequency, SphericalHarmonics (degree <= 5), OneBlob, TriangleWave, Composite (Concatenation), Empty",
              "  networks: FullyFusedMLP, CutlassMLP; activations: None, ReLU, LeakyReLU, SiLU, Exponential, Sine,",
              "  Sigmoid, Squareplus, Softplus, Tanh")


def add_parsers(sub, formatter=argparse.HelpFormatter) -> None:
    from inshade.codegen import FILTERS, STORAGE_MODES
    from inshade.codegen.targets import TARGETS
    from inshade.quantize import PRECISIONS

    compute_targets = [name for name, t in TARGETS.items() if not t.opengl]

    from .shown_as import SHOWN_AS

    p = sub.add_parser("convert", help="an ONNX file or a tiny-cuda-nn model -> a bundle, checked through the GL driver",
                       description="Convert a network into a bundle folder (bundle.json + weights.safetensors): "
                                   "each op is lowered onto inshade's components, the GLSL is run through the GL "
                                   "driver on sample inputs and compared with the source (max |glsl - source| "
                                   "under 1e-5 * max(1, |source|)), then the folder is written. MODEL.onnx is "
                                   "checked against onnxruntime. CONFIG.json PARAMS is a tiny-cuda-nn model (its "
                                   "JSON config and the flat parameter vector its torch bindings save); its GLSL "
                                   "is checked against the bundle's torch twin, since tiny-cuda-nn needs CUDA and "
                                   "does not run here (docs/tcnn.md says what the lowering was tested against). "
                                   "Torch modules go in from Python: inshade.export(module, example_input, "
                                   "folder). --ops lists what each source can hold. A technique's own files become "
                                   "whole assets (--ops lists them: e.g. instant-ngp NeRF snapshots).")
    p.add_argument("source", nargs="?", metavar="MODEL",
                   help="model.onnx (opsets 13 and newer), or a tiny-cuda-nn config.json: {\"encoding\", "
                        "\"network\"} (either may be left out), with \"n_input_dims\" / \"n_output_dims\" in "
                        "it or given by --inputs / --outputs, or a file a technique converts (--ops)")
    p.add_argument("params", nargs="?", metavar="PARAMS",
                   help="a tiny-cuda-nn model's parameters: state_dict()[\"params\"] as .npy, .safetensors, "
                        ".pt/.pth (torch.load with weights_only=True) or raw little-endian .bin (its length "
                        "says fp16 or fp32)")
    p.add_argument("-o", "--output", metavar="FOLDER", help="bundle folder to write (refused if it holds files, "
                                                            "unless --force)")
    p.add_argument("--inputs", type=int, metavar="N", help="tiny-cuda-nn: the model's input width "
                                                           "(n_input_dims), when the config does not say")
    p.add_argument("--outputs", type=int, metavar="M", help="tiny-cuda-nn: the model's output width "
                                                            "(n_output_dims), when the config does not say")
    p.add_argument("--params-key", metavar="KEY", help="tiny-cuda-nn: the tensor to read from a .pt or "
                                                       ".safetensors file holding several (default: params)")
    p.add_argument("--as", dest="as_", choices=SHOWN_AS,
                   help="what the network is, so `inshade render` / `view` can draw it (image: uv -> colour)")
    p.add_argument("--colour", choices=("srgb", "linear"),
                   help="with --as image: the colour the network gives: srgb for one fitted to image pixels as "
                        "files hold them, linear for light (not given: linear, with a warning)")
    p.add_argument("--name", help="bundle name (default: the file's stem)")
    p.add_argument("--semantic", action="append", metavar="PORT=SEMANTIC",
                   help="a port's semantic, e.g. --semantic rgb=srgb for colour fitted to sRGB pixels (the "
                        "display decodes it); repeatable")
    p.add_argument("--example", metavar="INPUTS.npy",
                   help="[N, inputs] float32 rows for the check (default: 64 uniform rows in [-1, 1] for ONNX, "
                        "[0, 1] for tiny-cuda-nn); random rows in their range are added")
    p.add_argument("--target", action="append", choices=compute_targets, default=[], dest="targets",
                   help="also check the code in this shading language on its driver (wgpu on this machine's Vulkan "
                        "device), against the source; repeatable")
    p.add_argument("--precision", choices=PRECISIONS, default="f32",
                   help="store the dense weights at this precision: f16 (half the bytes) or i8 (a quarter: int8 "
                        "codes times a scale per output row); the code is checked against the quantized network's "
                        "twin and the twin's distance from the source is printed beside it")
    p.add_argument("--max-error", type=float, metavar="E",
                   help="instead of --precision: the cheapest precision per dense layer (i8, f16, else f32) whose "
                        "network stays within E of the source on the check's inputs; the choice is printed")
    p.add_argument("--no-check", action="store_true", help="write without running the GLSL against the source")
    p.add_argument("--force", action="store_true", help="write into a folder that already holds files")
    p.add_argument("--ops", action="store_true", help="list the operations each source lowers, and exit")
    p.set_defaults(func=cmd_convert)

    p = sub.add_parser("eval", help="run a bundle's GLSL on inputs.npy through the GL driver",
                       description="Evaluate a bundle's generated GLSL on a batch through the GL driver (the "
                                   "same pass the parity tests use): INPUTS.npy [N, inputs] float32 -> "
                                   "OUTPUTS.npy [N, outputs] float32, outputs concatenated in the bundle's order. "
                                   "A one-input bundle whose input has a tensor shape (an ONNX [1, N, F] or "
                                   "[H, W, F] input) also takes that shape, and gives its one output shaped the "
                                   "same way.")
    p.add_argument("bundle", metavar="BUNDLE", help="bundle folder, or an asset with one network")
    p.add_argument("inputs", metavar="INPUTS.npy", help="[N, inputs] array (.npy, read without pickles)")
    p.add_argument("-o", "--output", required=True, metavar="OUTPUTS.npy", help="file to write (- : standard output)")
    p.add_argument("--storage", choices=STORAGE_MODES, default="auto", help="dense weight placement")
    p.add_argument("--lut-filter", choices=FILTERS, default="exact", help="lookup array filtering path")
    p.add_argument("--target", choices=("330", *compute_targets), default="330",
                   help="the code run: OpenGL's GLSL (330) through the GL driver, or wgsl / vulkan / hlsl / slang through "
                        "wgpu on this machine's Vulkan device")
    p.set_defaults(func=cmd_eval)


def cmd_convert(args) -> int:
    from .lowering import ConvertError

    if args.ops:
        print(ops_text())
        return 0
    if args.source is None or args.output is None:
        raise ConvertError("convert: give MODEL and -o FOLDER (or --ops)")
    source = Path(args.source)
    kind = SOURCES.get(source.suffix.lower())
    converter = technique_converters().get(source.suffix.lower())
    if converter is not None:
        return _convert_asset(converter, source, args)
    if kind is None:
        known = [*SOURCES, *technique_converters()]
        raise ConvertError(f"{source}: unknown model format {source.suffix or '(no suffix)'!r} "
                           f"(inshade convert reads {', '.join(known)}; torch modules: inshade.export)")
    example = _read_npy(args.example) if args.example else None
    semantics = {}
    for item in args.semantic or []:
        port, sep, semantic = item.partition("=")
        if not sep or not port or not semantic:
            raise ConvertError(f"--semantic {item!r}: expected PORT=SEMANTIC, e.g. rgb=srgb")
        semantics[port] = semantic
    common = dict(name=args.name, as_=args.as_, check=not args.no_check, force=args.force, quiet=args.quiet,
                  example=example, semantics=semantics, colour=args.colour, targets=args.targets,
                  precision=args.precision, max_error=args.max_error)
    if kind == "tiny-cuda-nn":
        if args.params is None:
            raise ConvertError(f"{source}: a tiny-cuda-nn config needs its PARAMS file too: "
                               f"inshade convert {source} PARAMS -o FOLDER")
        from .tcnn import convert

        bundle = convert(source, args.params, args.output, n_input_dims=args.inputs, n_output_dims=args.outputs,
                         params_key=args.params_key, **common)
    else:
        tcnn_only = [o for o, v in (("PARAMS", args.params), ("--inputs", args.inputs), ("--outputs", args.outputs),
                                    ("--params-key", args.params_key)) if v is not None]
        if tcnn_only:
            raise ConvertError(f"{source}: {tcnn_only[0]} is for tiny-cuda-nn models (CONFIG.json PARAMS); an ONNX "
                               "file holds its own weights and shapes")
        from .export import convert_onnx as convert

        bundle = convert(source, args.output, **common)
    if not args.quiet:
        print(f"wrote {args.output}: {len(bundle.nodes)} nodes, {bundle.in_dim} -> {bundle.out_dim} lanes",
              file=sys.stderr)
    return 0


def technique_converters() -> dict[str, str]:
    """File suffix -> the module that converts such files into a technique's asset (the registry's
    ``converts``)."""
    from inshade.technique import techniques

    return {suffix.lower(): module for t in techniques() for suffix, module in t.converts.items()}


def _convert_asset(module: str, source: Path, args) -> int:
    """A file that becomes a whole asset (e.g. an instant-ngp snapshot): the technique's converter
    writes the folder; the network options of bundle conversions do not apply."""
    import importlib

    from .lowering import ConvertError

    given = [o for o, v in (("PARAMS", args.params), ("--inputs", args.inputs), ("--outputs", args.outputs),
                            ("--params-key", args.params_key), ("--as", args.as_), ("--example", args.example),
                            ("--semantic", args.semantic), ("--name", args.name),
                            ("--precision", args.precision != "f32"), ("--max-error", args.max_error)) if v]
    if given:
        raise ConvertError(f"{source}: {given[0]} does not apply to a {source.suffix} file (it converts to a whole asset)")
    if args.output is None:
        raise ConvertError(f"convert: give -o FOLDER for {source}")
    said = importlib.import_module(module).convert(source, args.output, force=args.force, quiet=args.quiet)
    if not args.quiet:
        print(said, file=sys.stderr)
    return 0


def _read_npy(path):
    import numpy as np

    from .lowering import ConvertError

    try:
        return np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError) as exc:   # missing, empty, not a plain .npy array (pickles refused)
        raise ConvertError(f"{path}: cannot read as a .npy array ({exc})") from None


def cmd_eval(args) -> int:
    import numpy as np

    from inshade.bundle import load
    from inshade.files import atomic_files

    from .check import evaluate
    from .lowering import ConvertError

    from inshade.port_layout import LayoutError, from_rows, port_shape, to_rows

    bundle = load(args.bundle)
    x = _read_npy(args.inputs)
    shaped = len(bundle.inputs) == 1 and bundle.inputs[0].shape is not None and x.ndim != 2
    if shaped:   # the input's own tensor shape (bundle.json inputs[0].shape): rows in, the outputs shaped back
        try:
            x, sizes = to_rows(x, port_shape(bundle.inputs[0]), args.inputs)
        except LayoutError as exc:
            raise ConvertError(str(exc)) from None
    if x.ndim != 2 or x.shape[1] != bundle.in_dim or x.dtype.kind not in "fiu":
        raise ConvertError(f"{args.inputs}: shape {list(x.shape)} ({x.dtype}); {bundle.name} takes "
                           f"[N, {bundle.in_dim}] numbers")
    out, renderer, storage = evaluate(bundle, x.astype(np.float32), storage=args.storage, lut_filter=args.lut_filter,
                                      target=args.target)
    if shaped and len(bundle.outputs) == 1:
        out = from_rows(out, port_shape(bundle.outputs[0]), sizes)
    if args.output == "-":   # the .npy bytes on standard output
        np.save(sys.stdout.buffer, out)
        sys.stdout.buffer.flush()
        return 0
    with atomic_files(args.output) as tmp:
        with open(tmp, "wb") as f:
            np.save(f, out)
    if not args.quiet:
        print(f"wrote {args.output}: {list(out.shape)} ({renderer}, storage {storage})", file=sys.stderr)
    return 0


def ops_text() -> str:
    """What each source lowers (``inshade convert --ops``)."""
    import importlib

    from inshade.components import COMPONENTS

    from .onnx_model import HANDLERS as ONNX_OPS

    lines = ["files that become a technique's asset (inshade convert FILE -o FOLDER):"]
    lines += [f"  {suffix}: {importlib.import_module(module).SOURCE}" for suffix, module in technique_converters().items()]
    lines += ["", "torch modules (inshade.export; ATen ops as torch.export records them):"]
    try:
        from .torch_module import HANDLERS as TORCH_OPS
        lines += _wrap(sorted(TORCH_OPS))
    except ImportError:
        lines.append("  (torch is not installed: pip install -e '.[train]')")
    lines += ["  plus any op whose inputs are all constants (evaluated by torch at export)",
              "", "ONNX (inshade convert model.onnx; opsets 13 and newer):"]
    lines += _wrap(sorted(ONNX_OPS))
    lines += ["  plus any node whose inputs are all constants (evaluated by onnx's reference evaluator)",
              "", "tiny-cuda-nn (inshade convert config.json params; docs/tcnn.md):"]
    lines += list(TCNN_PARTS)
    lines += ["", "bundle components they lower to:"]
    lines += _wrap(sorted(COMPONENTS))
    lines += ["", "refused: ops that mix the batch (reductions, softmax or BatchNorm statistics over it), "
              "data-dependent control flow, outputs wider than 4 x GL_MAX_DRAW_BUFFERS lanes, grids past the GL "
              "limits, products of two computed tensors"]
    return "\n".join(lines)


def _wrap(names: list[str], width: int = 100) -> list[str]:
    lines, line = [], " "
    for name in names:
        if len(line) + len(name) + 2 > width:
            lines.append(line.rstrip(", "))
            line = " "
        line += f" {name},"
    lines.append(line.rstrip(","))
    return lines
