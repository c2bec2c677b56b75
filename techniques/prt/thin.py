"""Thin geometry for learnt transfer: how the shadow-ray scheme changes the
ground truth, and training points sampled near occluders.

- ``shadow_study(sdf, n_points, n_dirs, schemes)``: the transfer of ``n_points`` surface samples
  under several shadow-ray schemes (origin offset along the normal, hit threshold, step cap, step
  scale), each against a reference trace with a tiny offset and threshold, a small step scale and
  a step cap no ray reaches (``REFERENCE``), the same directions for every scheme (so the
  differences are visibility alone). Reports diffuse-shading PSNR vs the reference (noon sky,
  albedo 0.8), the fraction of rays whose visibility flips, undecided rays and trace seconds.
- the subset of points near occluders (near_occluders.py ``occluder_proximity``), where the
  transfer changes fast and the network's error concentrates; training samples there with
  ``sample_near_occluders``.

    python -m inshade.techniques.prt.thin study --sdf trained/prt_mechanical/sdf.json
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time

import numpy as np
import torch

from inshade.techniques.prt import transfer as T
from inshade.techniques.prt.transfer_directions import hemisphere_directions, project_visibility
from inshade.techniques.prt.near_occluders import occluder_proximity
from inshade.techniques.prt.transfer_surface import sample_sdf_surface

# (offset in hit_eps units, shadow hit threshold in hit_eps units, step cap, step scale, escape): with
# escape the origin also moves out by max(0, -sdf(p)) (a sample still inside the solid after its
# Newton projection -- sharp edges -- would otherwise start its rays inside and see nothing)
SCHEMES = {
    "current": (T.OFFSET_EPS, 1.0, T.SHADOW_STEPS, 0.9, False),
    "current, 2000 steps": (T.OFFSET_EPS, 1.0, 2000, 0.9, False),
    "offset 4, threshold 1/10": (T.OFFSET_EPS, 0.1, 2000, 0.9, False),
    "offset 1, threshold 1/4": (1.0, 0.25, 2000, 0.9, False),
    "offset 1/2, threshold 1/8": (0.5, 0.125, 2000, 0.9, False),
}
REFERENCE = (0.1, 0.01, 20000, 0.5, True)


def scheme_transfer(sdf, p, n, dirs, scheme):
    """Transfer [N, 16] (and occluded / undecided [N, D]) of points p, n along ``dirs`` [N, D, 3]."""
    scene = sdf.scene
    hit_eps = float(scene.trace["hit_eps"])
    off, eps, steps, step_scale, escape = scheme
    center = torch.tensor(scene.center, dtype=torch.float32)
    with torch.no_grad():
        lift = off * hit_eps + (sdf(p).neg().clamp_min(0.0) if escape else 0.0)
        lift = torch.as_tensor(lift, dtype=torch.float32).expand(p.shape[0])
        o = (p + n * lift[:, None])[:, None].expand_as(dirs).reshape(-1, 3)
        occ, und = T.shadow_trace(sdf, o, dirs.reshape(-1, 3), center, float(scene.radius), step_scale,
                                  eps * hit_eps, steps)
    occ, und = occ.reshape(dirs.shape[:2]), und.reshape(dirs.shape[:2])
    return project_visibility(~occ, dirs), occ, und


def _diffuse(t, env):
    return (t.numpy().astype(np.float64) @ env) * 0.8 / math.pi


def _psnr(a, b):
    mse = float(np.mean((np.clip(a, 0, 1) - np.clip(b, 0, 1)) ** 2))
    return 10 * math.log10(1.0 / mse) if mse > 0 else math.inf


def shadow_study(sdf, n_points: int = 400, n_dirs: int = 128, schemes=None, seed: int = 7, subsets=None) -> dict:
    """See the module docstring. ``subsets``: {name: fn(p, n) -> bool mask} reported separately."""
    from inshade.codegen.sdf import environment_sh

    schemes = schemes or SCHEMES
    p, n = sample_sdf_surface(sdf, n_points, seed=seed)
    # samples the Newton projection left inside the solid (|d| up to hit_eps at creases, where the
    # normal is unreliable too) have no well-defined truth: the reference would start inside
    with torch.no_grad():
        good = sdf(p).abs() <= 0.1 * float(sdf.scene.trace["hit_eps"])
    dropped = int((~good).sum())
    p, n = p[good], n[good]
    n_points = int(p.shape[0])
    dirs = hemisphere_directions(n, n_dirs, torch.Generator().manual_seed(seed))
    env = np.asarray(environment_sh("noon", 0.0, 4), np.float64)
    start = time.perf_counter()
    ref, occ_r, und_r = scheme_transfer(sdf, p, n, dirs, REFERENCE)
    out = {"points": n_points, "dropped_off_surface": dropped, "dirs": n_dirs,
           "reference": dict(zip(("offset", "threshold", "steps", "step_scale", "escape"), REFERENCE)),
           "reference_undecided": float(und_r.float().mean()), "reference_seconds": time.perf_counter() - start,
           "schemes": []}
    masks = {"all": torch.ones(n_points, dtype=torch.bool), **{k: f(p, n) for k, f in (subsets or {}).items()}}
    sref = _diffuse(ref, env)
    for name, scheme in schemes.items():
        start = time.perf_counter()
        t, occ, und = scheme_transfer(sdf, p, n, dirs, scheme)
        row = {"scheme": name, "offset": scheme[0], "threshold": scheme[1], "steps": scheme[2],
               "step_scale": scheme[3], "escape": scheme[4], "seconds": time.perf_counter() - start,
               "undecided": float(und.float().mean()), "ray_flips": float((occ != occ_r).float().mean())}
        s = _diffuse(t, env)
        for k, m in masks.items():
            mm = m.numpy()
            row[f"psnr_{k}"] = _psnr(s[mm], sref[mm]) if mm.any() else None
            row[f"points_{k}"] = int(mm.sum())
        out["schemes"].append(row)
    return out


def _study(args) -> int:
    from inshade.geometry.sdf import load_sdf
    from inshade.techniques.prt.twin import sdf_module

    sdf = sdf_module(load_sdf(args.sdf))
    delta = 0.03 * float(sdf.scene.radius)
    res = shadow_study(sdf, args.points, args.dirs,
                       subsets={"near_occluders": lambda p, n: occluder_proximity(sdf, p, n, delta) > 0.2})
    res["sdf"] = args.sdf
    res["near_occluders"] = f"occluder_proximity(delta = {delta:.4g}) > 0.2"
    if args.experiments:
        res["learnt"] = json.loads(open(args.experiments).read())
    if args.out:
        from inshade.bench.harness import machine, write_report

        res["machine"] = machine(torch=torch.__version__)
        write_report(args.out, "prt_thin", res, _markdown)
    else:
        print(json.dumps(res, indent=1))
    return 0


def _markdown(r: dict) -> str:
    from inshade.bench.harness import machine_markdown, markdown_table

    ref = r["reference"]
    lines = ["# Thin geometry: the SDF shadow-ray scheme vs a fine reference trace", "", machine_markdown(r["machine"]), "",
             f"`{r['sdf']}`: {r['points']} surface samples ({r['dropped_off_surface']} dropped: left off the surface "
             f"by the Newton projection), {r['dirs']} cosine-weighted rays each, the same directions for every scheme. "
             f"Reference: offset {ref['offset']} hit_eps, threshold {ref['threshold']} hit_eps, step scale "
             f"{ref['step_scale']}, {ref['steps']} steps ({r['reference_seconds']:.0f} s). PSNR of the diffuse shading "
             f"(noon sky, albedo 0.8) vs the reference; near occluders: {r['near_occluders']}.", ""]
    rows = [[s["scheme"], f"{s['offset']:g}", f"{s['threshold']:g}", s["steps"], f"{s['psnr_all']:.2f}",
             f"{s['psnr_near_occluders']:.2f} ({s['points_near_occluders']})", f"{100 * s['ray_flips']:.2f} %",
             f"{s['undecided']:.1e}", f"{s['seconds']:.1f}"] for s in r["schemes"]]
    lines += markdown_table(["scheme", "offset", "threshold", "steps", "PSNR all", "PSNR near occluders (n)",
                             "rays flipped", "undecided", "trace s"], rows)
    if r.get("learnt"):
        lines += ["", "Learnt transfer (k = 64, 4 layers, 16000 steps of 512, lr 1e-2) on 40000 samples x 128 rays: "
                  "held-out PSNR against 512-ray transfer at 1000 uniform samples:", ""]
        lines += markdown_table(["training samples", "position octaves", "held-out diffuse PSNR", "held-out PSNR (16 lanes)",
                                 "train s"],
                                [[e["samples"], e["pos_freqs"], f"{e['heldout_diffuse_psnr']:.2f}",
                                  f"{e['heldout_psnr']:.2f}", e["seconds"]] for e in r["learnt"]])
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m inshade.techniques.prt.thin", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    s = sub.add_parser("study", help="the ground truth under each shadow scheme vs a fine reference trace")
    s.add_argument("--sdf", required=True)
    s.add_argument("--points", type=int, default=400)
    s.add_argument("--dirs", type=int, default=128)
    s.add_argument("--out", help="write prt_thin.json / prt_thin.md there (default: JSON to stdout)")
    s.add_argument("--experiments", help="a JSON list of learnt-transfer runs to add to the report")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    return _study(args)


if __name__ == "__main__":
    sys.exit(main())
