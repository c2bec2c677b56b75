"""A glTF file's geometry: the default scene's node tree walked (transforms composed down it, every
instance of a mesh, EXT_mesh_gpu_instancing included), each primitive read from its accessors or
its KHR_draco_mesh_compression bitstream, strips and fans made triangles, flat normals where a
primitive has none, and MikkTSpace tangents. A primitive is a dict of arrays in world space
(``position``, ``faces``, ``normal``, ``tangent``, ``uv``, ``uv1``, ``material``, ``where``).
"""
from __future__ import annotations

import math

import numpy as np

from .gltf_codecs import DRACO, CodecError, draco_attributes
from .gltf_document import GltfDocument
from .gltf_types import COMPONENTS, MODES, WIDTHS, field_error, floats


def scene_primitives(doc: GltfDocument) -> list[dict]:
    """Every primitive the default scene draws (scene-less files: every root node), in world space."""
    scenes = doc.entries("scenes")
    if scenes:
        index = doc.doc.get("scene", 0)
        roots = doc.entry("scenes", index, "scene").get("nodes", [])
    else:
        children = {c for n in doc.entries("nodes") if isinstance(n, dict) for c in n.get("children", [])}
        roots = [i for i in range(len(doc.entries("nodes"))) if i not in children]
    parts: list[dict] = []
    for root in roots:
        _walk(doc, root, np.eye(4), parts, set(), "scenes.nodes")
    if not parts:
        raise field_error("scenes", "the default scene draws no triangles (no node with a mesh)")
    return parts


def _walk(doc: GltfDocument, index, parent: np.ndarray, parts: list, seen: set, where: str) -> None:
    """Append node ``index``'s primitives (each instance once) and its children's to ``parts``."""
    node = doc.entry("nodes", index, where)
    if index in seen:
        raise field_error(f"nodes[{index}]", "is its own ancestor (the node graph must be a tree)")
    seen = seen | {index}
    w = f"nodes[{index}]"
    world = parent @ _node_matrix(node, w)
    if "mesh" in node:
        instances = [world]
        inst = (node.get("extensions") or {}).get("EXT_mesh_gpu_instancing")
        if inst is not None:
            where_instances = f"{w}.extensions.EXT_mesh_gpu_instancing"
            instances = [world @ m for m in _instances(doc, inst.get("attributes", {}), where_instances)]
        mesh = doc.entry("meshes", node["mesh"], f"{w}.mesh")
        prims = mesh.get("primitives")
        if not isinstance(prims, list) or not prims:
            raise field_error(f"meshes[{node['mesh']}].primitives", "must be a non-empty list")
        for k, prim in enumerate(prims):
            local = _primitive(doc, prim, f"meshes[{node['mesh']}].primitives[{k}]")
            for m in instances:
                parts.append(_transformed(local, m))
    for child in node.get("children", []):
        _walk(doc, child, world, parts, seen, f"{w}.children")


def _instances(doc: GltfDocument, attributes: dict, where: str) -> list[np.ndarray]:
    """EXT_mesh_gpu_instancing's per-instance matrices (in the node's space)."""
    arrays = {k: doc.accessor(v, f"{where}.attributes.{k}") for k, v in attributes.items()
              if k in ("TRANSLATION", "ROTATION", "SCALE")}
    if not arrays:
        raise field_error(f"{where}.attributes", "needs TRANSLATION, ROTATION or SCALE")
    counts = {len(a) for a in arrays.values()}
    if len(counts) != 1:
        raise field_error(f"{where}.attributes", "accessors of different counts")
    n = counts.pop()
    t = arrays.get("TRANSLATION", np.zeros((n, 3)))
    r = arrays.get("ROTATION", np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)))
    s = arrays.get("SCALE", np.ones((n, 3)))
    return [_trs(t[i], r[i], s[i]) for i in range(n)]


def _primitive(doc: GltfDocument, prim: dict, where: str) -> dict:
    """One primitive in its mesh's space: triangles, its attributes as float64, flat normals if it has none."""
    mode = prim.get("mode", 4)
    if mode not in MODES:
        raise field_error(f"{where}.mode", f"{mode!r} is not a glTF primitive mode")
    if mode not in (4, 5, 6):
        raise field_error(f"{where}.mode", f"{MODES[mode]}: only triangles (4, and strips 5 / fans 6) can be drawn")
    attrs = prim.get("attributes")
    if not isinstance(attrs, dict) or "POSITION" not in attrs:
        raise field_error(f"{where}.attributes", "needs POSITION")
    draco = (prim.get("extensions") or {}).get(DRACO)
    decoded, draco_idx = _draco(doc, draco, f"{where}.extensions.{DRACO}") if draco is not None else ({}, None)

    def attribute(name: str) -> np.ndarray:
        if name in decoded:
            return _draco_values(doc, attrs[name], decoded[name], f"{where}.attributes.{name}")
        return doc.accessor(attrs[name], f"{where}.attributes.{name}")

    pos = attribute("POSITION")
    if pos.shape[1] != 3:
        raise field_error(f"{where}.attributes.POSITION", "must be VEC3")
    v = len(pos)
    if draco_idx is not None:
        idx = draco_idx
    elif "indices" in prim:
        idx = doc.accessor(prim["indices"], f"{where}.indices")
        if idx.shape[1] != 1 or idx.dtype != np.int64:
            raise field_error(f"{where}.indices", "must be an unsigned int SCALAR accessor")
        idx = idx[:, 0]
        if len(idx) and (idx.min() < 0 or idx.max() >= v):
            raise field_error(f"{where}.indices", f"index {int(idx.max())} out of range: POSITION has {v} vertices")
    else:
        idx = np.arange(v)
    faces = _triangles(idx, mode, where)
    out = {"position": pos, "faces": faces, "uv": None, "normal": None, "tangent": None,
           "material": prim.get("material"), "needs_tangent": True, "where": where}
    out["uv1"] = None
    for key, name, width in (("normal", "NORMAL", 3), ("tangent", "TANGENT", 4), ("uv", "TEXCOORD_0", 2),
                             ("uv1", "TEXCOORD_1", 2)):
        if name in attrs:
            a = attribute(name)
            if a.shape != (v, width):
                raise field_error(f"{where}.attributes.{name}", f"must be {v} elements of {width} components "
                                  f"(POSITION's count), got {list(a.shape)}")
            out[key] = a.astype(np.float64)
    if out["material"] is not None:
        doc.entry("materials", out["material"], f"{where}.material")
    if out["normal"] is None:   # the spec: flat normals; a vertex per face corner
        out = _flat(out)
    return out


def _draco(doc: GltfDocument, ext, where: str) -> tuple[dict, np.ndarray]:
    if not isinstance(ext, dict):
        raise field_error(where, "must be an object")
    data, _ = doc.view(ext.get("bufferView"), f"{where}.bufferView")
    try:
        return draco_attributes(data, ext, where)
    except CodecError as exc:
        raise field_error(exc.where, exc.what) from None


def _draco_values(doc: GltfDocument, index, values: np.ndarray, where: str) -> np.ndarray:
    """A Draco-decoded attribute as ``accessor`` returns it: its accessor gives count and width,
    and whether integers are normalised."""
    a = doc.entry("accessors", index, where)
    if a.get("componentType") not in COMPONENTS or a.get("type") not in WIDTHS:
        raise field_error(f"accessors[{index}]", "not a glTF accessor layout")
    if values.shape != (a.get("count"), WIDTHS[a["type"]]):
        raise field_error(where, f"the Draco bitstream holds {list(values.shape)} values; accessors[{index}] "
                          f"declares {a.get('count')} x {WIDTHS[a['type']]}")
    _, norm = COMPONENTS[a["componentType"]]
    if a.get("normalized") and norm is not None and values.dtype.kind in "iu":
        return np.maximum(values.astype(np.float64) / norm, -1.0)
    return values.astype(np.float64 if values.dtype.kind == "f" else np.int64)


def _node_matrix(node: dict, where: str) -> np.ndarray:
    if "matrix" in node:
        m = np.array(floats(node["matrix"], 16, f"{where}.matrix")).reshape(4, 4).T   # column-major
        return m
    t = floats(node.get("translation", (0.0, 0.0, 0.0)), 3, f"{where}.translation")
    r = floats(node.get("rotation", (0.0, 0.0, 0.0, 1.0)), 4, f"{where}.rotation")
    s = floats(node.get("scale", (1.0, 1.0, 1.0)), 3, f"{where}.scale")
    return _trs(t, r, s)


def _trs(t, r, s) -> np.ndarray:
    x, y, z, w = (float(c) for c in r)
    norm = math.sqrt(x * x + y * y + z * z + w * w) or 1.0
    x, y, z, w = x / norm, y / norm, z / norm, w / norm
    rot = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                    [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                    [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    m = np.eye(4)
    m[:3, :3] = rot * np.asarray(s, np.float64)[None, :]
    m[:3, 3] = t
    return m


def _triangles(idx: np.ndarray, mode: int, where: str) -> np.ndarray:
    if mode == 4:
        if len(idx) % 3:
            raise field_error(f"{where}.indices", f"{len(idx)} indices: triangles need a multiple of 3")
        return idx.reshape(-1, 3)
    if len(idx) < 3:
        raise field_error(f"{where}.indices", f"{len(idx)} indices: a strip or fan needs at least 3")
    k = np.arange(len(idx) - 2)
    if mode == 5:   # strip: every other triangle swaps its first two corners to keep the winding
        even = k % 2 == 0
        return np.stack([np.where(even, idx[k], idx[k + 1]), np.where(even, idx[k + 1], idx[k]), idx[k + 2]], 1)
    return np.stack([np.full_like(k, idx[0]), idx[k + 1], idx[k + 2]], 1)


def _flat(p: dict) -> dict:
    corner = p["faces"].reshape(-1)
    out = dict(p)
    for key in ("position", "uv", "uv1", "tangent"):
        if p[key] is not None:
            out[key] = p[key][corner]
    v = out["position"]
    f = np.arange(len(corner)).reshape(-1, 3)
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    out["normal"] = np.repeat(n, 3, axis=0)
    out["faces"] = f
    return out


def _transformed(p: dict, m: np.ndarray) -> dict:
    out = dict(p)
    lin = m[:3, :3]
    out["position"] = p["position"] @ lin.T + m[:3, 3]
    normal_m = np.linalg.inv(lin).T
    n = p["normal"] @ normal_m.T
    out["normal"] = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    if p["tangent"] is not None:
        t = p["tangent"][:, :3] @ lin.T
        t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-300)
        flip = -1.0 if np.linalg.det(lin) < 0 else 1.0
        out["tangent"] = np.concatenate([t, p["tangent"][:, 3:] * flip], 1)
    if np.linalg.det(lin) < 0:
        out["faces"] = p["faces"][:, ::-1]
    return out


def mikktspace_tangents(v: np.ndarray, n: np.ndarray, uv_gltf: np.ndarray, f: np.ndarray) -> np.ndarray:
    """[V, 4] tangents as MikkTSpace makes them (the spec's rule where a file has none): corners
    with equal position, normal and uv share one; each face's uv-gradient tangent, projected into
    the corner's normal plane and normalised, weighted by the corner's angle in that plane; w from
    the bitangent's side, negated for glTF's v-down uv (as three.js does for glTF).
    Checked against the reference MikkTSpace (npm ``mikktspace``) in tests/geometry/test_gltf.py."""
    key = np.concatenate([v, n, uv_gltf], 1)
    _, group, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    g = inverse[f]
    e1, e2 = v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]
    d1, d2 = uv_gltf[f[:, 1]] - uv_gltf[f[:, 0]], uv_gltf[f[:, 2]] - uv_gltf[f[:, 0]]
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    sign = np.sign(det)[:, None]
    t_face = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) * sign
    b_face = (e2 * d1[:, 0:1] - e1 * d2[:, 0:1]) * sign
    t = np.zeros((len(group), 3))
    b = np.zeros((len(group), 3))
    for c in range(3):
        nc = n[f[:, c]]
        a, q = v[f[:, (c + 1) % 3]] - v[f[:, c]], v[f[:, (c + 2) % 3]] - v[f[:, c]]
        a -= nc * np.sum(nc * a, 1, keepdims=True)
        q -= nc * np.sum(nc * q, 1, keepdims=True)
        cos = np.sum(a * q, 1) / np.maximum(np.linalg.norm(a, axis=1) * np.linalg.norm(q, axis=1), 1e-300)
        angle = np.arccos(np.clip(cos, -1.0, 1.0))[:, None]
        tc = t_face - nc * np.sum(nc * t_face, 1, keepdims=True)
        tc /= np.maximum(np.linalg.norm(tc, axis=1, keepdims=True), 1e-300)
        np.add.at(t, g[:, c], tc * angle)
        np.add.at(b, g[:, c], b_face * np.abs(det)[:, None])
    ng = n[group]
    length = np.linalg.norm(t, axis=1, keepdims=True)
    fallback = np.cross(ng, np.where(np.abs(ng[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]]))
    t = np.where(length > 1e-12, t / np.maximum(length, 1e-300),
                 fallback / np.linalg.norm(fallback, axis=1, keepdims=True))
    w = np.where(np.sum(np.cross(ng, t) * b, 1) < 0.0, 1.0, -1.0)
    return np.concatenate([t, w[:, None]], 1)[inverse]

