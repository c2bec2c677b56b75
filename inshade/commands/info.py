"""`inshade info`: a bundle or an asset described: its scene, the settings it takes and every
bundle it uses, with the parity envelope; --json has everything."""
from __future__ import annotations

import json
import logging

from .common import asset_networks, resolve

log = logging.getLogger("inshade")


def add_parser(sub) -> None:
    p = sub.add_parser("info", help="describe a bundle or an asset",
                       description="Validate and describe a bundle, or an asset: its scene, the --set settings "
                                   "it takes (types, ranges, defaults) and every bundle it uses. Long training "
                                   "histories are summarised; --json has everything.")
    p.add_argument("bundle",
                   help="bundle folder, asset folder (scene.json), scene.json or shipped asset name")
    p.add_argument("--json", action="store_true", help="machine-readable output (everything)")
    p.set_defaults(func=cmd_info)


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

    src = resolve(args.bundle)
    scene, nets = asset_networks(src)
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
