"""What an imported network is, said by its user (``as_=`` / ``--as``): the port semantics, the
``render`` metadata and (for 3D) the scene.json that let ``inshade render`` and ``inshade view``
draw it with the generic programs. Applied after the parity check: the network itself is checked
as the user wrote it.

- ``image``: one 2-wide input (uv in [0, 1]^2, (0, 0) bottom left) -> a 1, 3 or 4-wide colour,
  drawn by passes/field2d.frag over the unit square. Its ``colour`` is asked for: "linear" (light),
  or "srgb" for a network fitted to image pixels as files hold them (decoded by the pass, so the
  PNG shows the values the network gives); not given, it is taken as linear and a warning says so,
  since an sRGB-fitted network shown as linear light looks pale.
- ``sdf``: position (3) -> distance (1), in the user's world units, sphere traced by
  passes/sdf_diffuse.frag (environment light). The traced bound is the sphere around the example
  points' box; the network SDF contract (codegen/network_sdf.py) normalises positions into that
  sphere, so the bundle gets an affine node before the user's graph (back to world positions)
  and one after it (distance in bound radii). ``step_scale`` 0.5: the tracer stays safe for a
  network whose gradient reaches 2 (an exact SDF has 1).
- ``field``: position (3) + direction (3) -> rgb (3) + density (1), ray marched through the example
  positions' box by passes/imported_field.frag (techniques/imported).
"""
from __future__ import annotations

import numpy as np

from inshade.bundle import Bundle
from inshade.scene.builder import display_modes, requires, scene_json

from .lowering import ConvertError

SHOWN_AS = ("image", "sdf", "field")
COLOURS = {"linear": "linear_rgb", "srgb": "srgb"}   # an image's colour -> its output port's semantic
SDF_STEP_SCALE = 0.5
FIELD_SAMPLES = 128        # steps across the box diagonal
SIZE = 256


def check_colour(as_: str | None, colour: str | None) -> None:
    if colour is None:
        return
    if colour not in COLOURS:
        raise ConvertError(f"colour: {colour!r} is not one of {', '.join(COLOURS)}")
    if as_ != "image":
        raise ConvertError(f"colour: goes with as_=\"image\" (--as image), not {as_!r}")


def colour_warning(bundle: Bundle, as_: str, colour: str | None, semantics: dict | None) -> str | None:
    """The line that says an image's colour was assumed (None when it was said, one way or another)."""
    if as_ != "image" or colour is not None:
        return None
    shown = bundle.meta["render"]["output"]
    if semantics and shown in semantics:
        return None
    return (f"as image: the output {shown!r} is taken as linear light; a network fitted to image pixels as files "
            "hold them (PNG, PIL, skimage.data: sRGB-encoded) shows pale that way: say colour=\"srgb\" "
            "(--colour srgb), or colour=\"linear\" to keep this and drop the warning")


def apply_shown_as(bundle: Bundle, as_: str, example: np.ndarray, colour: str | None = None
                   ) -> tuple[Bundle, dict | None]:
    """(the bundle as ``as_`` says, the scene.json to write beside it or None); ``example`` the
    check's input rows [N, in_dim] (their box is the 3D domain); ``colour``: an image's (COLOURS)."""
    if as_ == "image":
        return _image(bundle, colour or "linear")
    return {"sdf": _sdf, "field": _field}[as_](bundle, np.asarray(example, np.float64))


def _ports(bundle: Bundle) -> str:
    return ", ".join(f"{p.name}[{p.dim}]" for p in bundle.inputs) + " -> " + \
        ", ".join(f"{p.name}[{p.dim}]" for p in bundle.outputs)


def _image(bundle: Bundle, colour: str) -> tuple[Bundle, None]:
    meta = dict(bundle.meta)
    ins, outs = [dict(p) for p in meta["inputs"]], [dict(p) for p in meta["outputs"]]
    if len(ins) != 1 or ins[0]["dim"] != 2:
        raise ConvertError(f"as image: the network needs one input of 2 lanes (uv); it is {_ports(bundle)}")
    dims = {p.name: p.dim for p in bundle.outputs}
    shown = next((p for p in outs if dims[p["name"]] in (1, 3, 4)), None)
    if shown is None:
        raise ConvertError("as image: no output of 1, 3 or 4 lanes (grey, rgb, rgba) to show")
    ins[0]["semantic"] = "uv"
    shown["semantic"] = COLOURS[colour]
    meta.update(inputs=ins, outputs=outs,
                render={"program": "passes/field2d.frag", "width": SIZE, "height": SIZE,
                        "input": ins[0]["name"], "output": shown["name"]})
    return Bundle(meta, bundle.tensors), None


def _box(example, lanes, what) -> tuple[np.ndarray, np.ndarray]:
    pts = example[:, lanes]
    lo, hi = pts.min(0), pts.max(0)
    if not np.all(hi > lo):
        raise ConvertError(f"as {what}: the example positions span no volume ({lo.tolist()} .. {hi.tolist()}); give "
                           "example points that fill the domain to draw")
    return lo, hi


def _orbit(center, radius) -> dict:
    return {"type": "orbit", "fov_y": 40.0, "target": [float(c) for c in center], "distance": float(radius) * 2.9,
            "yaw": -30.0, "pitch": -18.0}


def _scene(bundle: Bundle, program: str, camera: dict, **fields) -> dict:
    return scene_json(bundle.name, f"{bundle.name} (exported)", program, (SIZE, SIZE), camera=camera, bookmarks={},
                      lights=[], display=display_modes(), requires=requires(), **fields)


def _sdf(bundle: Bundle, example) -> tuple[Bundle, dict]:
    if bundle.in_dim != 3 or bundle.out_dim != 1 or len(bundle.inputs) != 1:
        raise ConvertError(f"as sdf: the network needs one input of 3 lanes (position) and 1 output lane "
                           f"(distance); it is {_ports(bundle)}")
    lo, hi = _box(example, slice(0, 3), "sdf")
    center, radius = (lo + hi) / 2, float(np.linalg.norm(hi - lo) / 2)
    frame_in = _affine("sdf_world", bundle.inputs[0].name, np.full(3, radius), center)
    frame_out = _affine("sdf_distance", bundle.outputs[0].node, np.full(1, 1.0 / radius), np.zeros(1))
    meta = _wrapped(bundle, frame_in, frame_out)
    meta["inputs"][0]["semantic"] = "position"
    meta["outputs"][0]["semantic"] = "sdf"
    eps = 1e-3 * radius
    meta["render"] = {"sdf": {"center": center.tolist(), "radius": radius, "albedo": [0.8, 0.8, 0.8],
                              "trace": {"max_steps": 256, "step_scale": SDF_STEP_SCALE, "hit_eps": eps,
                                        "normal_eps": eps}}}
    tensors = {**bundle.tensors, **frame_in[1], **frame_out[1]}
    scene = _scene(bundle, "passes/sdf_diffuse.frag", _orbit(center, radius), networks=[], sdf={"network": "."},
                   environment={"sky": "noon", "rotation": 0.0, "degree": 4})
    return Bundle(meta, tensors), scene


def _affine(node_id: str, source: str, scale, offset):
    node = {"id": node_id, "type": "affine", "inputs": [source], "params": {}}
    return node, {f"{node_id}.scale": np.asarray(scale, np.float32), f"{node_id}.offset": np.asarray(offset, np.float32)}


def _wrapped(bundle: Bundle, frame_in, frame_out) -> dict:
    """The graph with ``frame_in`` between the input and its readers, ``frame_out`` on the output."""
    meta = {k: v for k, v in bundle.meta.items()}
    port = bundle.inputs[0].name
    nodes = [{**n, "inputs": [frame_in[0]["id"] if s == port else s for s in n["inputs"]]} for n in meta["nodes"]]
    outs = [dict(p) for p in meta["outputs"]]
    if outs[0]["node"] == port:
        outs[0]["node"] = frame_in[0]["id"]
        frame_out[0]["inputs"] = [frame_in[0]["id"]]
    meta["inputs"] = [dict(p) for p in meta["inputs"]]
    meta["nodes"] = [frame_in[0], *nodes, frame_out[0]]
    outs[0]["node"] = frame_out[0]["id"]
    meta["outputs"] = outs
    return meta


def _field(bundle: Bundle, example) -> tuple[Bundle, dict]:
    if bundle.in_dim != 6 or bundle.out_dim != 4:
        raise ConvertError(f"as field: the network needs position + direction (6 input lanes) and rgb + density "
                           f"(4 output lanes); it is {_ports(bundle)}")
    lo, hi = _box(example, slice(0, 3), "field")
    meta = dict(bundle.meta)
    ins, outs = [dict(p) for p in meta["inputs"]], [dict(p) for p in meta["outputs"]]
    if len(ins) == 2:
        ins[0]["semantic"], ins[1]["semantic"] = "position", "direction"
    diagonal = float(np.linalg.norm(hi - lo))
    meta.update(inputs=ins, outputs=outs, render={"field": {
        "box": [lo.tolist(), hi.tolist()], "step": diagonal / FIELD_SAMPLES, "max_steps": 2 * FIELD_SAMPLES,
        "background": [0.0, 0.0, 0.0]}})
    center, radius = (lo + hi) / 2, diagonal / 2
    scene = _scene(bundle, "passes/imported_field.frag", _orbit(center, radius),
                   networks=[{"bundle": ".", "prefix": "net"}])
    return Bundle(meta, bundle.tensors), scene



def with_semantics(bundle: Bundle, semantics: dict) -> Bundle:
    """The bundle with the ports named in ``semantics`` ({name: semantic}) given those semantics."""
    meta = dict(bundle.meta)
    ports = {p["name"]: p for p in (*meta["inputs"], *meta["outputs"])}
    for name, semantic in semantics.items():
        if name not in ports:
            raise ConvertError(f"semantics: no port named {name!r} (ports: {', '.join(ports)})")
        if not isinstance(semantic, str) or not semantic:
            raise ConvertError(f"semantics: {name}: a semantic is a word (e.g. srgb, uv, position), got {semantic!r}")
        ports[name]["semantic"] = semantic
    return Bundle(meta, bundle.tensors)
