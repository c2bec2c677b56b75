"""What an imported network is, said by its user (``as_=`` / ``--as``): the port semantics and the
``render`` field that let ``inshade render`` and ``inshade view`` draw it with the generic programs.

- ``image``: one 2-wide input (uv in [0, 1]^2, (0, 0) bottom left) -> a 1, 3 or 4-wide colour in
  linear light, drawn by passes/field2d.frag over the unit square.
"""
from __future__ import annotations

from inshade.bundle import Bundle

from .lowering import ConvertError

SHOWN_AS = ("image",)


def apply_shown_as(bundle: Bundle, as_: str) -> Bundle:
    meta = dict(bundle.meta)
    ins, outs = [dict(p) for p in meta["inputs"]], [dict(p) for p in meta["outputs"]]
    if as_ == "image":
        if len(ins) != 1 or ins[0]["dim"] != 2:
            have = ", ".join(f"{p['name']}[{p['dim']}]" for p in ins)
            raise ConvertError(f"as image: the network needs one input of 2 lanes (uv), it has {have}")
        dims = {p.name: p.dim for p in bundle.outputs}
        shown = next((p for p in outs if dims[p["name"]] in (1, 3, 4)), None)
        if shown is None:
            raise ConvertError("as image: no output of 1, 3 or 4 lanes (grey, rgb, rgba) to show")
        ins[0]["semantic"] = "uv"
        shown["semantic"] = "linear_rgb"
        meta["render"] = {"program": "passes/field2d.frag", "width": 256, "height": 256,
                          "input": ins[0]["name"], "output": shown["name"]}
    meta.update(inputs=ins, outputs=outs)
    return Bundle(meta, bundle.tensors)
