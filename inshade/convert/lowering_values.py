"""The bundle graph a lowering grows: values (runs of global lanes), nodes, the inputs and outputs,
and the bundle they make. A node is emitted only where a value is computed, and a ``select`` node
only where a computation needs lanes in an order no value has."""
from __future__ import annotations

import numpy as np

from inshade.bundle import FORMAT, MAX_INPUT_DIM, VERSION, Bundle
from inshade.components import MAX_WIDTH

from .lanes import ConvertError, Feat, constant_in, shape_text


class ValueGraph:
    """The values and nodes of a ``Lowering`` (its dataclass fields hold them)."""

    # --- values --------------------------------------------------------------------------
    def _new_value(self, vid: str, width: int) -> np.ndarray:
        if width > MAX_WIDTH:
            raise ConvertError(f"a value {width} lanes wide; the widest a bundle takes is {MAX_WIDTH}")
        base = len(self.lane_value)
        self.values[vid] = (base, width)
        self.lane_value += [vid] * width
        self.lane_index += list(range(width))
        return np.arange(base, base + width)

    def _id(self, kind: str) -> str:
        k = self._counts.get(kind, 0)
        self._counts[kind] = k + 1
        return f"{kind}{k}"

    def input(self, name: str, dim: int, semantic: str = "generic", shape=None) -> Feat:
        """A bundle input of ``dim`` lanes; ``shape``: its full tensor shape, None on the batch axes
        (port_layout.py), when it is not plain rows."""
        if dim > MAX_INPUT_DIM:
            posed = f" (shape {shape_text(shape)}: each row holds the non-batch axes)" if shape else ""
            raise ConvertError(f"input {name!r}: {dim} lanes wide{posed}; an input takes at most {MAX_INPUT_DIM}")
        port = {"name": name, "dim": int(dim), "semantic": semantic}
        if shape is not None and list(shape) != [None, dim]:
            port["shape"] = list(shape)
        self.inputs.append(port)
        return Feat(self._new_value(name, dim).reshape(1, dim), 0)

    def _sources(self, lanes: np.ndarray) -> list[str]:
        """The node inputs whose concatenation is exactly ``lanes`` (whole values in order), else
        one ``select`` node over the values involved."""
        lanes = np.asarray(lanes, np.int64).reshape(-1)
        out, i = [], 0
        while i < len(lanes):
            vid = self.lane_value[lanes[i]]
            base, width = self.values[vid]
            if lanes[i] != base or i + width > len(lanes) or not np.array_equal(lanes[i:i + width],
                                                                                np.arange(base, base + width)):
                break
            out.append(vid)
            i += width
        if i == len(lanes):
            return out
        involved = list(dict.fromkeys(self.lane_value[k] for k in lanes))
        offsets, at = {}, 0
        for vid in involved:
            offsets[vid] = at
            at += self.values[vid][1]
        picks = [offsets[self.lane_value[k]] + self.lane_index[k] for k in lanes]
        return [self._node("select", involved, {"lanes": picks}, len(picks))]

    def _node(self, kind: str, sources: list[str], params: dict, width: int, tensors: dict | None = None) -> str:
        vid = self._id(kind)
        self.nodes.append({"id": vid, "type": kind, "inputs": list(sources), "params": params})
        for slot, a in (tensors or {}).items():
            self.tensors[f"{vid}.{slot}"] = np.ascontiguousarray(a, np.float32)
        self._new_value(vid, width)
        return vid

    def _emit(self, kind: str, feat_lanes: np.ndarray, params: dict, width: int, tensors=None) -> np.ndarray:
        """A node over the given lanes (flattened); its output lanes."""
        if np.size(feat_lanes) == 0:
            raise ConvertError("computes from a tensor with no elements (an empty slice or split)")
        vid = self._node(kind, self._sources(feat_lanes), params, width, tensors)
        base, _ = self.values[vid]
        return np.arange(base, base + width)

    def resolve(self, f: Feat) -> Feat:
        """``f`` with its pending scalar multiply emitted."""
        if f.pending is None:
            return f
        return self._elementwise_affine(Feat(f.lanes, f.batch), np.float32(f.pending), np.float32(0.0))

    def constant(self, like: Feat, values) -> Feat:
        """A constant as lanes, shaped like ``like`` but for its own sizes (1 on the batch axis):
        0 * x + c of one lane x of ``like`` (finite inputs give exactly c)."""
        values = constant_in(np.asarray(values, np.float32), like.batch, like.rank)
        lane = np.asarray(like.lanes).reshape(-1)[:1]
        src = np.broadcast_to(lane, values.size)
        out = self._emit("affine", src, {}, values.size, {"scale": np.zeros(values.size), "offset": values.reshape(-1)})
        return Feat(out.reshape(values.shape), like.batch)

    @staticmethod
    def broadcast_shape(f: Feat, *shapes) -> tuple:
        rank = max([f.rank, *(len(s) for s in shapes)])
        if rank != f.rank:
            raise ConvertError(f"a constant of rank {rank} widens a rank-{f.rank} tensor past its batch axis")
        try:
            return np.broadcast_shapes(f.shape, *shapes)
        except ValueError:
            raise ConvertError(f"shapes {list(f.shape)} and {[list(s) for s in shapes]} do not broadcast") from None

    # --- outputs and the bundle ------------------------------------------------------------
    def output(self, name: str, f: Feat, semantic: str = "generic", batch_axes: int = 1, leading: int = 1) -> None:
        """An output port: its row is ``f`` with the batch axis taken out, the other axes in order;
        ``batch_axes``: how many axes of the source's tensor the batch axis stands for; ``leading``:
        the inputs' batch axes were [1, .., 1, batch] (a traced [H, W, F]), so an output that keeps
        them in front has them all as batch axes."""
        f = self.resolve(f)
        if any(o["name"] == name for o in self.outputs):
            raise ConvertError(f"output {name!r} is named twice")
        if f.lanes.size == 0:
            raise ConvertError(f"output {name!r} has no elements (an empty slice or split)")
        sources = self._sources(np.moveaxis(f.lanes, f.batch, 0).reshape(-1))
        if len(sources) == 1:
            vid = sources[0]
        else:   # several whole values side by side: one identity node concatenates them
            vid = self._node("identity", sources, {}, f.lanes.size)
        port = {"name": name, "node": vid, "semantic": semantic}
        shape = [*f.shape[:f.batch], *[None] * batch_axes, *f.shape[f.batch + 1:]]
        if leading > 1 and f.batch == leading - 1 and all(n == 1 for n in f.shape[:f.batch]):
            shape = [None] * leading + shape[leading:]
        if shape != [None, f.lanes.size]:
            port["shape"] = shape
        self.outputs.append(port)

    def bundle(self, kind: str, name: str, provenance: dict, render: dict | None = None) -> Bundle:
        used = self._live()
        meta = {"format": FORMAT, "version": VERSION, "kind": kind, "name": name, "inputs": self.inputs,
                "nodes": [n for n in self.nodes if n["id"] in used], "outputs": self.outputs,
                "provenance": provenance, "metrics": {}}
        if render:
            meta["render"] = render
        tensors = {k: v for k, v in self.tensors.items() if k.split(".")[0] in used}
        return Bundle(meta, tensors)

    def _live(self) -> set[str]:
        """Nodes an output depends on (a value computed and never used is dropped)."""
        by_id = {n["id"]: n for n in self.nodes}
        live, stack = set(), [o["node"] for o in self.outputs]
        while stack:
            vid = stack.pop()
            if vid in live or vid not in by_id:
                continue
            live.add(vid)
            stack += by_id[vid]["inputs"]
        return live
