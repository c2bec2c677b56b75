"""``inshade.export``: the torch.onnx.export of shaders. A user's torch module becomes a bundle
folder (bundle.json + weights.safetensors) whose GLSL is checked against the module through the
GL driver before anything is written; an ONNX file goes the same way (``convert_onnx``).

    import inshade
    net = torch.nn.Sequential(torch.nn.Linear(2, 64), torch.nn.ReLU(), torch.nn.Linear(64, 3))
    inshade.export(net, torch.rand(16, 2), "my_net", as_="image")
    # max |glsl - source| = 1.2e-07 (rule 1e-05): ok
    # inshade render my_net -o shot.png
"""
from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np

from inshade.provenance import recorded_at

from .lowering import ConvertError, Lowering
from .shown_as import SHOWN_AS, apply_shown_as, check_colour, colour_warning, with_semantics

KIND = "imported"   # the kind of a user's own network (techniques/imported draws the 3D ones)


def export(module, example_input, folder, *, name: str | None = None, input_names=None, output_names=None,
           check: bool = True, as_: str | None = None, force: bool = False, quiet: bool = False,
           limits: dict | None = None, check_storage: str = "auto", semantics: dict | None = None,
           colour: str | None = None, targets=(), precision: str | dict = "f32", max_error: float | None = None):
    """Capture ``module`` on ``example_input`` (a [batch, features] tensor, or a tuple of them, one
    per input; an input of higher rank, e.g. [1, N, F] or [H, W, F], takes its leading axes as the
    batch, and `inshade eval` then takes and gives arrays of that rank), lower it onto bundle components, check its GLSL against the module through the GL
    driver (unless ``check=False``), and write the bundle into ``folder`` (refused if it holds
    files, unless ``force``). ``as_``: what the network is, for ``inshade render`` / ``view``
    ("image": uv -> colour; "sdf": xyz -> distance; "field": xyz + direction -> rgb + density).
    ``limits``: the GL limits the GLSL must fit (e.g. a target GPU's; default: this driver's);
    ``check_storage``: the dense weight placement the check compiles (codegen's storage modes; "auto"
    on a software driver reads the weights from a texture where literals would compile for long:
    check_storage.py);
    ``semantics``: {port name: semantic}, e.g. ``{"y": "srgb"}`` for colour fitted to sRGB pixels
    (the display decodes it to linear). ``colour`` ("srgb" | "linear", with ``as_="image"``): what the
    shown colour is; a network fitted to image pixels (PNG, PIL, skimage.data: sRGB-encoded) is "srgb".
    Not given, it is taken as linear, with a warning. ``targets``: shading languages beside OpenGL's
    GLSL whose code is checked too, each on its own driver (``"wgsl"``, ``"vulkan"``, ``"hlsl"``,
    ``"slang"``: codegen.targets); the bundle is written only if every check holds. ``precision``: how
    the dense weights are stored ("f32", "f16", "i8", or {node id: precision}; inshade/quantize.py): the
    shader is checked against the quantized network's twin and the twin's distance from the module is
    reported beside it; ``max_error``: instead, the cheapest precision per layer whose twin stays within
    this of the module on the example (convert/precision.py).
    Returns the saved ``Bundle``. Raises ``ConvertError`` (one line) for what cannot be lowered."""
    import torch

    from inshade import asset_folder

    from .torch_module import TRACE_BATCH, LeadingAxes, TorchLowering, capture

    if not isinstance(module, torch.nn.Module):
        raise ConvertError(f"module: expected a torch.nn.Module, got {type(module).__name__}")
    if as_ is not None and as_ not in SHOWN_AS:
        raise ConvertError(f"as_: {as_!r} is not one of {', '.join(SHOWN_AS)}")
    examples = list(example_input) if isinstance(example_input, (tuple, list)) else [example_input]
    for i, x in enumerate(examples):
        if not isinstance(x, torch.Tensor) or x.ndim < 2 or not x.is_floating_point():
            what = f"a {x.ndim}-D {x.dtype} tensor" if isinstance(x, torch.Tensor) else type(x).__name__
            raise ConvertError(f"example_input[{i}]: expected a [batch, features] float tensor, got {what}")
    lead = max(x.ndim for x in examples) - 1   # batch axes: all but the last (features)
    if lead > 1 and len({tuple(x.shape[:-1]) for x in examples}) != 1:
        shapes = ", ".join(str(list(x.shape)) for x in examples)
        raise ConvertError(f"example_input: shapes {shapes}: every input needs the same leading (batch) axes")
    if len({len(x) for x in examples}) != 1:
        raise ConvertError("example_input: every input needs the same number of rows (the batch)")
    names = list(input_names or (["x"] if len(examples) == 1 else [f"x{i}" for i in range(len(examples))]))
    if len(names) != len(examples):
        raise ConvertError(f"input_names: {len(names)} names for {len(examples)} inputs")
    folder = Path(folder)
    asset_folder.claim(folder, folder.name, force=force, option="folder", force_option="force=True")

    # the trace batch: the example's rows, repeated to TRACE_BATCH (the batch axis is found by its size).
    # An input of rank > 2 ([1, N, F], [H, W, F]) takes its leading axes as the batch: it is traced
    # as [1, .., 1, TRACE_BATCH, F], and its rows are the leading axes flattened.
    rows = [x.detach().float().cpu().reshape(-1, x.shape[-1]) if lead > 1 else x.detach().float().cpu()
            for x in examples]
    posed = (1,) * (lead - 1)
    trace = [r[torch.arange(TRACE_BATCH) % len(r)].reshape(*posed, TRACE_BATCH, *r.shape[1:]) for r in rows]
    gm, consts, user = capture(module, tuple(trace))
    lowering = Lowering()
    specs = [(n, tuple(int(d) for d in x.shape[1:]), "generic", lead) for n, x in zip(names, rows)]
    outputs = TorchLowering(lowering, consts, TRACE_BATCH).run(gm, user, specs)
    flat = _flat(outputs)
    out_names = list(output_names or (["y"] if len(flat) == 1 else [f"y{i}" for i in range(len(flat))]))
    if len(out_names) != len(flat):
        raise ConvertError(f"output_names: {len(out_names)} names for {len(flat)} outputs")
    for out_name, f in zip(out_names, flat):
        if not hasattr(f, "lanes"):
            raise ConvertError(f"output {out_name!r} is a constant (it does not depend on the input)")
        lowering.output(out_name, f, leading=lead)
    provenance = {"source": "torch", "module": type(module).__qualname__, "exported_by": "inshade.export",
                  "torch": torch.__version__,
                  **recorded_at()}
    bundle = lowering.bundle(KIND, name or folder.name, provenance)
    source = module if lead == 1 else LeadingAxes(module, lead)
    return finish(bundle, source, [r.numpy() for r in rows], folder, check=check, quiet=quiet, limits=limits, as_=as_,
                  check_storage=check_storage, semantics=semantics, colour=colour, targets=targets,
                  precision=precision, max_error=max_error)


def finish(bundle, source, examples, folder: Path, *, check: bool, quiet: bool, limits=None,
           as_: str | None = None, check_storage: str = "auto", semantics: dict | None = None,
           colour: str | None = None, targets=(), precision: str | dict = "f32", max_error: float | None = None):
    """Store the dense weights at ``precision`` (or, ``max_error``, the cheapest per layer within it),
    plan the GLSL once against ``limits`` (default: the driver's), check it (through the GL driver,
    against ``source``, or against the quantized network's twin with the quantization reported) and
    the code of each of ``targets`` (on its driver, planned against its API's limits), record the
    checks, make the bundle what ``as_`` (and ``colour``, for an image) says, write it (and its
    scene.json for 3D) into ``folder``, which the caller claimed before any work. Returns the written
    bundle."""
    import json

    from inshade.codegen import generate
    from inshade.codegen.limits import limit
    from inshade.files import atomic_write

    from .check import check as run_check, check_inputs, finite_rows
    from .check_storage import quick_storage

    check_colour(as_, colour)
    flat = np.concatenate([np.asarray(e, np.float32).reshape(len(e), -1) for e in examples], 1)
    fp32_bundle, shapes, checked = bundle, [np.shape(e)[1:] for e in examples], source
    if max_error is not None or precision != "f32":   # the shader is checked against the quantized twin
        bundle, checked = _quantized(bundle, source, flat, shapes, precision, max_error, quiet)
    if limits is None and check:
        from inshade.runtime.context import gl_info, shared_context

        limits = gl_info(shared_context())
    lanes = 4 * limit(limits or {}, "GL_MAX_DRAW_BUFFERS")
    if bundle.out_dim > lanes:
        raise ConvertError(f"outputs: {bundle.out_dim} lanes in all; a pass writes at most {lanes} "
                           f"(4 per draw buffer, GL_MAX_DRAW_BUFFERS {lanes // 4}): split the network")
    generated = None   # planned once against the limits, then run by the check
    if limits is not None:
        try:
            for storage in dict.fromkeys(("auto", check_storage)):   # the default plan must fit, whatever is checked
                generated = generate(bundle, storage=storage, limits=limits)
        except ValueError as exc:   # LimitError: a grid or a layer past the limits
            raise ConvertError(f"the generated GLSL does not fit the GL limits: {exc}") from None
    if check:
        check_storage, generated, why = quick_storage(bundle, check_storage, limits, generated)
        if why and not quiet:
            print(why, file=sys.stderr)
        x = check_inputs(flat)
        left_out = len(flat) - len(finite_rows(flat))
        if left_out and not quiet:
            print(f"example: {left_out} of {len(flat)} rows hold NaN or infinities; left out of the check (the "
                  "random rows span the finite ones)", file=sys.stderr)
        try:
            result = run_check(checked, bundle, x, shapes=shapes, limits=limits, storage=check_storage,
                               generated=generated)
        except ValueError as exc:
            raise ConvertError(f"the generated GLSL cannot run here: {exc}") from None
        if bundle is not fp32_bundle:
            result = dataclasses.replace(result, reference="twin")
        if not quiet:
            print(result.line(), file=sys.stderr)
        if not result.ok:
            raise ConvertError(f"{result.line()}; nothing written (check=False / --no-check writes it anyway)")
        bundle.meta["provenance"]["check"] = {**result.record(), "example_rows_left_out": left_out}
        if bundle is not fp32_bundle:
            _record_quantization(bundle, fp32_bundle, source, x, shapes, quiet)
        if targets:
            bundle.meta["provenance"]["check"]["targets"] = _check_targets(checked, bundle, x, shapes, targets, quiet)
    scene = None
    if as_ is not None:
        bundle, scene = apply_shown_as(bundle, as_, flat, colour)
        warning = colour_warning(bundle, as_, colour, semantics)
        if warning and not quiet:
            print(warning, file=sys.stderr)
    if semantics:
        bundle = with_semantics(bundle, semantics)
    bundle.save(folder)   # claimed by the caller before any work
    if scene is not None:
        atomic_write(folder / "scene.json", json.dumps(scene, indent=1) + "\n")
    return bundle


def _parts(bundle, x, shapes) -> list[np.ndarray]:
    from .check import per_input

    return [p.reshape(len(p), *shape) for p, shape in zip(per_input(bundle, x), shapes)]


def _quantized(bundle, source, flat, shapes, precision, max_error, quiet: bool):
    """(the bundle at its precision, what the shader is checked against: its twin); with
    ``max_error`` the precision per layer is chosen on the check's inputs and the choice printed."""
    from inshade.quantize import quantized

    from .check import check_inputs
    from .precision import choose, describe, twin

    if max_error is not None:
        try:
            precision, lines = choose(bundle, source, _parts(bundle, check_inputs(flat), shapes), float(max_error))
        except ValueError as exc:
            raise ConvertError(str(exc)) from None
        if not quiet:
            print("\n".join(["precision per layer:", *(f"  {line}" for line in lines)]), file=sys.stderr)
    try:
        out = quantized(bundle, precision)
    except ValueError as exc:
        raise ConvertError(f"precision: {exc}") from None
    out.meta["provenance"]["precision"] = {"requested": describe(precision),
                                           **({"max_error": float(max_error)} if max_error is not None else {})}
    return out, twin(out)


def _record_quantization(bundle, fp32_bundle, source, x, shapes, quiet: bool) -> None:
    from .precision import quantization

    q = quantization(source, bundle, fp32_bundle, _parts(bundle, x, shapes),
                     bundle.meta["provenance"]["precision"]["requested"])
    if not quiet:
        print(q.line(), file=sys.stderr)
    bundle.meta["provenance"]["precision"].update(q.record())


def convert_onnx(source, folder, *, name: str | None = None, as_: str | None = None, check: bool = True,
            force: bool = False, quiet: bool = False, example=None, semantics: dict | None = None,
            colour: str | None = None, targets=(), precision: str | dict = "f32", max_error: float | None = None):
    """An ONNX file (or ModelProto) -> a bundle folder (its dense weights at ``precision``, or within
    ``max_error``, as ``export``), its GLSL (and the code of each of ``targets``) checked against
    onnxruntime on ``example`` ([N, in_dim] rows, or one input's whole tensor; default uniform [-1, 1])
    plus random rows in its range."""
    from inshade import asset_folder
    from inshade.port_layout import LayoutError, port_shape, to_rows

    from .onnx_model import to_bundle

    folder = Path(folder)
    asset_folder.claim(folder, folder.name, force=force, option="-o")
    bundle, model, lowering = to_bundle(source, name=name)
    if example is None:
        example = np.random.default_rng(0).uniform(-1, 1, (64, bundle.in_dim)).astype(np.float32)
    example = np.asarray(example, np.float32)
    if example.ndim != 2 and len(bundle.inputs) == 1:
        try:
            example = to_rows(example, port_shape(bundle.inputs[0]), "example")[0]
        except LayoutError as exc:
            raise ConvertError(str(exc)) from None
    if example.ndim != 2 or example.shape[1] != bundle.in_dim:
        raise ConvertError(f"example: shape {list(example.shape)}; the model takes [N, {bundle.in_dim}] "
                           "(its inputs' rows side by side)")
    bounds = np.cumsum([0, *(p.dim for p in bundle.inputs)])
    parts = [example[:, a:b] for a, b in zip(bounds[:-1], bounds[1:])]
    return finish(bundle, model, parts, folder, check=check, quiet=quiet, as_=as_, semantics=semantics,
                  colour=colour, targets=targets, precision=precision, max_error=max_error)


def _check_targets(source, bundle, x, shapes, targets, quiet: bool) -> dict:
    """Each target's code on its driver against ``source`` (planned against the target API's limits): the
    records, or ConvertError naming the first target past the rule or unable to run."""
    from inshade.codegen.targets import TargetError, target as find_target

    from .check import check as run_check

    records = {}
    for name in dict.fromkeys(targets):
        try:
            if find_target(name).opengl:
                raise ValueError(f"{name} is OpenGL's GLSL, which is always checked; targets are the other "
                                 "shading languages")
            result = run_check(source, bundle, x, shapes=shapes, target=name)
            if "precision" in bundle.meta["provenance"]:   # checked against the quantized network's twin
                result = dataclasses.replace(result, reference="twin")
        except (TargetError, ValueError, RuntimeError) as exc:
            raise ConvertError(f"target {name}: {exc}") from None
        if not quiet:
            print(result.line(), file=sys.stderr)
        if not result.ok:
            raise ConvertError(f"{result.line()}; nothing written")
        records[name] = result.record()
    return records


def _flat(outputs) -> list:
    if isinstance(outputs, dict):
        return [v for item in outputs.values() for v in _flat(item)]
    if isinstance(outputs, (tuple, list)):
        return [v for item in outputs for v in _flat(item)]
    return [outputs]
