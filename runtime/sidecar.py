"""What a render's sidecar records: enough to re-render the same pixels (``inshade render --from``):
the GL renderer, the view, the settings, every bundle's digest, the codegen plan, and the lit
geometry with its environment."""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

from inshade.codegen.sdf import SDF_CHUNK, sdf_chunks
from inshade.scene.description import NetworkSdfRef


def render_info(scene, values: dict, gl: dict, *, samples: int, bundles, generated, sdf_bundle,
                camera, width: int, height: int, mode, split) -> dict:
    """The sidecar of one render of ``scene`` (``mode``: a DisplayMode; ``split``: None for the
    scene's own)."""
    common = {
        "gl": {k: gl[k] for k in ("vendor", "renderer", "version", "glsl_version", "software")},
        "spp": samples,   # samples averaged (accumulating programs; else 1)
        "render": {"program": scene.program, "width": width, "height": height,
                   "colour": "linear rgb, float32", "uv": "(0,0) bottom-left, pixel centres"},
        "scene": {"name": scene.name,
                  "path": str(Path(scene.source).resolve()) if scene.source else None},
        "view": {"camera": camera.to_dict(), "mode": mode.name.lower(),
                 "split": scene.split if split is None else float(split),
                 "settings": json.loads(json.dumps(values))},
    }
    if not bundles:
        return {**common, "bundle": None, "bundles": [], **geometry_info(scene, values, sdf_bundle)}
    primary = bundles[0]
    storages = {}
    for g in generated:
        for row in g.plan.rows:
            if row.storage and row.storage != "-":
                storages[row.storage] = storages.get(row.storage, 0) + 1
    totals = {}
    for g in generated:
        for k, v in g.plan.totals().items():
            totals[k] = totals.get(k, 0) + v
    ref = scene.networks[0]
    return {
        "bundle": {"name": primary.name, "kind": primary.kind,
                   "path": str(primary.path) if primary.path else None, "digest": primary.digest()},
        "bundles": [{"name": b.name, "digest": b.digest(), "prefix": n.prefix}
                    for b, n in zip(bundles, scene.networks)],
        **common,
        "render": {**common["render"], "input": primary.inputs[0].name,
                   "output": ref.output or primary.outputs[0].name,
                   "storage": values.get("storage", "auto"),
                   "lut_filter": values.get("lut_filter", "exact")},
        "plan": {"storage": storages, "totals": totals},
        **(geometry_info(scene, values, sdf_bundle) if scene.lit else {}),
    }


def geometry_info(scene, values: dict, sdf_bundle) -> dict:
    """Sidecar record of the lit geometry (SDF or mesh) and its environment."""
    sdf = scene.sdf
    env = dict(scene.environment)
    for name, s in scene.settings.items():
        if s.binding == "environment":
            env[s.target] = values[name]
    if sdf is None:
        mesh = scene.mesh
        # a built-in shape is recorded by name and parameters (geometry/shapes.py rebuilds it)
        source = {"path": str(mesh.path)} if mesh.path is not None else \
            {"path": None, "shape": mesh.shape, **mesh.params}
        return {"mesh": {**source, "name": mesh.name, "vertices": int(len(mesh.data.vertices)),
                         "faces": int(len(mesh.data.faces))}, "environment": env}
    if isinstance(sdf, NetworkSdfRef):
        record = {"path": str(sdf.path), "name": sdf_bundle.name, "network": True,
                  "digest": sdf_bundle.digest()}
    else:
        record = {"path": str(sdf.path) if sdf.path else None, "name": sdf.name, **sdf.to_dict(),
                  "chunk_sha256": hashlib.sha256(sdf_chunks(sdf)[SDF_CHUNK].encode()).hexdigest()}
    return {"sdf": record, "environment": env}
