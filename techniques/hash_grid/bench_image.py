"""The hash_grid bench's image application: the shipped hash grid + MLP, the MLP-only network of its
bytes and a DI texture cascade of its bytes, each drawn by passes/field2d.frag through the GL driver.

- Hash grid: the GL render at the collage's native size (one pixel a texel) against the target:
  PSNR on sRGB values (and in linear light), FLIP (LDR) when flip-evaluator imports.
- MLP-only (frequency encoding + ReLU MLP, the trainer's ``--arch mlp`` at the hash grid's bytes):
  its quality is the trainer's, measured beside the ship run and quoted from metrics.json
  (``mlp_baseline``); its frames are drawn here with untrained weights of that architecture (the
  pass evaluates every pixel once whatever the weights, so they time as trained ones do).
- DI cascade (models/texture_cascade.py: a 2D primary array into a 4D cascaded one, 8-bit cells,
  sized by ``plan`` to the hash grid's bytes), trained here on the same target for ``di_steps``:
  texture_cascade's recipe (stratified L1 under Adam, cosine decay, the last half on texel centres
  with the squared error, its "adam" finish), driven through models/indirection.py with one
  evaluation at the end, because ``compress`` evaluates the whole picture 20 times (7 s each at
  2048² on a 2-core CPU) and finishes with full-picture L-BFGS.
"""
from __future__ import annotations

import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from inshade.bench.harness import portable_path

from .bench_measure import ScenePass, asset_record, folder_bytes, load_asset, plan_summary


def image_quality(linear_rgba: np.ndarray, target: np.ndarray, use_flip: bool) -> dict:
    """PSNR of a linear render against the sRGB target, on sRGB values and in linear light (the
    render clipped to [0, 1] as shown); FLIP on the 8-bit sRGB pictures."""
    from inshade.metrics import flip, psnr, srgb_eotf, srgb_oetf

    linear = np.clip(linear_rgba[..., :3], 0.0, 1.0)
    shown = srgb_oetf(linear)
    q = {"psnr_srgb": round(psnr(shown, target), 3), "psnr_linear": round(psnr(linear, srgb_eotf(target)), 3)}
    if use_flip:
        to8 = (lambda x: np.rint(np.clip(x, 0, 1) * 255).astype(np.uint8))
        q["flip"] = round(float(flip(to8(target), to8(shown))), 5)
    return q


def variant_scene(asset: Path, bundle, folder: Path):
    """The asset's scene drawing another image bundle (saved into ``folder``), without its reference."""
    from inshade.scene.description import load_scene

    bundle.save(folder)
    data = json.loads((asset / "scene.json").read_text())
    data.pop("reference", None)
    data["display"] = {"mode": "final", "modes": ["final", "network"], "split": 0.5}
    data["networks"] = [{"bundle": ".", "prefix": "net", "output": bundle.outputs[0].name}]
    (folder / "scene.json").write_text(json.dumps(data))
    return load_scene(folder)


def drawn(ctx, scene, timing, size: int, target, use_flip: bool) -> dict:
    """A network's pass: the native-size render's quality (``target`` not None), first draw,
    frames and plan."""
    p = ScenePass(ctx, scene, timing)
    try:
        quality = image_quality(p.image(size), target, use_flip) if target is not None else None
        frames = p.frames()
        plan = plan_summary(p.plans()[0])
    finally:
        p.release()
    return {"quality": quality, "compile_s": p.compile_s, "first_draw_s": p.first_draw_s, "frames": frames,
            "plan": plan, "evaluations_per_pixel": 1.0, "flops_per_pixel": plan["flops"],
            "fetches_per_pixel": plan["fetches"]}


def fit_di(target: np.ndarray, nbytes: int, steps: int, batch: int, seed: int, name: str):
    """A DI texture cascade of at most ``nbytes`` fitted to ``target`` (sRGB [H, W, 3]); returns
    (bundle, record). texture_cascade.CompressionError when the bytes cannot hold a cascade."""
    import torch

    from inshade.models import indirection as di
    from inshade.models import texture_cascade as tc
    from inshade.models.threads import torch_threads

    h, w, k = target.shape
    sizing = tc.plan(target.shape, target.size / nbytes)
    flipped = np.ascontiguousarray(target[::-1])        # row 0 = v ~ 0 = bottom of the picture
    finish_at = steps - int(round(tc.DEFAULTS["finish"] * steps))
    with torch_threads(1):
        torch.manual_seed(seed)
        core = di.cascade(2, k, sizing.n_primary, sizing.n_cascaded, redundant=2, cascaded_init="mean",
                          cascaded_init_args={"target": target.reshape(-1, k)}, input_name="uv",
                          input_semantic="uv", output_name="values")
        start = time.perf_counter()
        di.train_cascade(core, di.image_sampler(flipped, batch, seed=seed), steps, lr=tc.DEFAULTS["lr"],
                         schedule=tc.DEFAULTS["schedule"], seed=seed, eval_every=max(steps, 1),
                         finish=(finish_at, di.texel_sampler(flipped, batch, seed=seed + 1), "mse")
                         if finish_at < steps else None, progress=False, desc=name)
        seconds = time.perf_counter() - start
    graph = tc.export_graph(core, k, decode=True)
    record = {"bytes": int(sizing.bytes), "n_primary": sizing.n_primary, "n_cascaded": sizing.n_cascaded,
              "steps": steps, "batch": batch, "train_seconds": round(seconds, 1)}
    render = {"program": tc.FIELD_PROGRAM, "width": w, "height": h, "input": "uv", "output": graph.outputs[0][0]}
    return graph.export(tc.KIND, name, metrics=record, render=render), record


def measure(folder: Path, opts, ctx, workdir: Path, log) -> dict:
    from inshade.models import texture_cascade as tc
    from inshade.scene.description import load_scene

    from . import image
    from .network import network_bytes

    bundle, metrics, s = load_asset(folder, image.KIND)
    target = image.load_target(s.size)
    size = s.size
    log(f"image: hash grid + MLP, {metrics['bytes']} bytes, drawn at {size}² and timed")
    ours = {"key": "hash_grid", "name": "hash grid + MLP", "bytes": int(metrics["bytes"]),
            "architecture": architecture(bundle),
            "quality_source": f"GL render at {size}² (field2d) against the target",
            "trainer_quality": {k: metrics[k] for k in ("psnr_srgb", "psnr_linear")},
            **drawn(ctx, load_scene(folder), opts.timing, size, target, opts.flip)}

    g = image.build(replace(s, arch="mlp"), s.seed)
    mlp_bundle = g.export(image.KIND, "hash_grid_image_mlp_only", render=bundle.meta["render"])
    base = metrics.get("mlp_baseline")
    log(f"image: MLP-only network, {network_bytes(g)} bytes, timed (untrained weights)")
    mlp = {"key": "mlp", "name": "MLP-only", "bytes": network_bytes(g), "architecture": architecture(mlp_bundle),
           "quality_source": (f"the trainer's, beside the ship run ({base['steps']} steps of {base['batch']} pixels, "
                              f"{base['network']}; metrics.json mlp_baseline); frames timed here with untrained "
                              "weights (every pixel evaluated once: they time as trained ones)") if base else
                             "not measured: the asset was trained without --baseline-steps",
           **drawn(ctx, variant_scene(folder, mlp_bundle, workdir / "image_mlp"), opts.timing, size, None, False)}
    mlp["quality"] = {k: base[k] for k in ("psnr_srgb", "psnr_linear")} if base else None

    rows = [ours, mlp]
    try:
        log(f"image: DI cascade of {metrics['bytes']} bytes, {opts.di_steps} steps")
        di_bundle, record = fit_di(target, int(metrics["bytes"]), opts.di_steps, opts.di_batch, s.seed,
                                   "hash_grid_image_di")
    except tc.CompressionError as e:
        rows.append({"key": "di", "name": "DI cascade", "not_compared": str(e)})
    else:
        rows.append({"key": "di", "name": "DI cascade", "bytes": record["bytes"], "architecture":
                     f"{record['n_primary']}² x 4 primary -> {record['n_cascaded']}^4 x 3 cascaded, 8-bit",
                     "training": record, "quality_source": f"GL render at {size}² (field2d, exact lookups); trained "
                     f"here: {record['steps']} steps, {record['train_seconds']:.0f} s",
                     **drawn(ctx, variant_scene(folder, di_bundle, workdir / "image_di"), opts.timing, size,
                             target, opts.flip)})
    return {"app": "image", "asset": portable_path(folder), "trained": asset_record(bundle, metrics),
            "kind": image.KIND, "size": size,
            "target": f"{size}x{size} photograph collage (techniques/hash_grid/mosaic.py)",
            "uncompressed_bytes": int(target.size), "bytes_file": folder_bytes(folder),
            "table_bytes": int(metrics["encoding"]["table_bytes_fp16"]), "rows": rows}


def architecture(bundle) -> str:
    """e.g. "hash_grid 12 levels x 2, 2^15 rows -> dense 64 -> dense 64 -> dense 3"."""
    parts = []
    for n in bundle.nodes:
        if n.type == "hash_grid":
            p = n.params
            parts.append(f"hash grid {p['levels']} levels x {p['features']}, 2^{p['log2_table_size']} rows")
        elif n.type == "frequency":
            parts.append(f"frequency ({n.params.get('n_freqs', '?')})")
        elif n.type == "dense" and n.id != "to_unit":
            parts.append(f"dense {n.params['out']}")
    return " -> ".join(parts)
