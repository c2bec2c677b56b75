"""Lowerings of whole layers: dense (and any map linear in its input), reductions, softmax and the
normalisations, multilinear lookups into constant grids."""
from __future__ import annotations

import numpy as np

from .lanes import ConvertError, Feat

MAX_DENSE_GROUPS = 64   # a linear layer repeated over a row's other axes (each repeat is a node)


class LayerLowering:
    """The layer operations of a ``Lowering``."""

    def softmax(self, f: Feat, axis: int) -> Feat:
        """exp(x - max) / sum, over a feature axis, in the order torch and onnxruntime compute it."""
        axis = axis % f.rank
        if axis == f.batch:
            raise ConvertError("softmax over the batch axis mixes the batch (one pixel's value would depend on all "
                               "the others)")
        top = self.reduce(f, "max", [axis], True)
        e = self.unary(self.binary("sub", f, top), "exp")
        return self.binary("div", e, self.reduce(e, "sum", [axis], True))

    def batch_norm(self, f: Feat, weight, bias, mean, var, eps: float) -> Feat:
        """BatchNorm with running statistics (eval / inference) as a per-channel affine (axis 1)."""
        if f.rank < 2:
            raise ConvertError("BatchNorm of a tensor without a channel axis")
        inv = 1.0 / np.sqrt(np.asarray(var, np.float64) + eps)
        w = np.ones_like(inv) if weight is None else np.asarray(weight, np.float64)
        b = np.zeros_like(inv) if bias is None else np.asarray(bias, np.float64)
        shape = [1] * f.rank
        shape[1] = -1
        return self.affine(f, (w * inv).astype(np.float32).reshape(shape),
                           (b - np.asarray(mean, np.float64) * w * inv).astype(np.float32).reshape(shape))

    def dense(self, f: Feat, weight: np.ndarray, bias: np.ndarray | None) -> Feat:
        """y = x W^T + b over the last axis of a [B, in] tensor (or W x over [in, B], batch last)."""
        f = self.resolve(f)
        weight = np.asarray(weight, np.float32)
        if f.rank > 2 and f.batch != f.rank - 1:   # [..., features]: one layer per position of the other axes
            if weight.ndim != 2 or weight.shape[1] != f.shape[-1]:
                raise ConvertError(f"linear layer: weight {list(weight.shape)} does not take {f.shape[-1]} features")
            rows = f.lanes.reshape(-1, f.shape[-1])
            if len(rows) > MAX_DENSE_GROUPS:
                raise ConvertError(f"a linear layer over the last axis of {list(f.shape)}: {len(rows)} rows per pixel, "
                                   f"more than {MAX_DENSE_GROUPS} layers")
            outs = [self.dense(Feat(r.reshape(1, -1), 0), weight, bias).lanes.reshape(-1) for r in rows]
            return Feat(np.stack(outs).reshape(*f.shape[:-1], weight.shape[0]), f.batch)
        if f.rank != 2:
            raise ConvertError(f"a linear layer on a rank-{f.rank} tensor (shape {list(f.shape)}) with the batch "
                               "last: inshade lowers it on [..., features]")
        feature_axis = 1 - f.batch
        if weight.ndim != 2 or weight.shape[1] != f.shape[feature_axis]:
            raise ConvertError(f"linear layer: weight {list(weight.shape)} does not take "
                               f"{f.shape[feature_axis]} features")
        lanes = f.lanes.reshape(-1)
        tensors = {"weight": weight}
        if bias is not None:
            tensors["bias"] = np.broadcast_to(np.asarray(bias, np.float32), (weight.shape[0],))
        out = self._emit("dense", lanes, {"out": int(weight.shape[0]), "bias": bias is not None},
                         weight.shape[0], tensors)
        return Feat(out.reshape((1, -1) if f.batch == 0 else (-1, 1)), f.batch)

    def linear_map(self, f: Feat, apply) -> Feat:
        """A map linear in ``f`` (an einsum of f with constants) as one dense layer. ``apply`` takes
        an array shaped like f with any size on its batch axis and returns the map's result; the
        matrix is read off the one-hot basis, and the output's batch axis is the one whose size
        follows the input's."""
        f = self.resolve(f)
        row = [n for a, n in enumerate(f.shape) if a != f.batch]
        lanes = int(np.prod(row))

        def on_basis(extra: int) -> np.ndarray:
            basis = np.concatenate([np.eye(lanes), np.zeros((extra, lanes))]).reshape(lanes + extra, *row)
            return np.asarray(apply(np.moveaxis(basis, 0, f.batch)), np.float64)

        try:
            y, y1 = on_basis(0), on_basis(1)
        except (ValueError, RuntimeError) as exc:   # numpy's and torch's words for operands that do not fit
            raise ConvertError(f"cannot be read as a linear map of the input ({str(exc).splitlines()[0][:100]})") from None
        moved = [a for a in range(y.ndim) if y.shape[a] != y1.shape[a]]
        if len(moved) != 1:
            raise ConvertError("sums over the batch axis (one pixel's value would depend on the others)")
        b = moved[0]
        matrix = np.moveaxis(y, b, 0).reshape(lanes, -1).T
        out = self.dense(Feat(np.moveaxis(f.lanes, f.batch, 0).reshape(1, -1), 0), matrix.astype(np.float32), None)
        out_row = [n for a, n in enumerate(y.shape) if a != b]
        return Feat(np.expand_dims(out.lanes.reshape(out_row), b), b)

    def reduce(self, f: Feat, op: str, axes, keepdim: bool) -> Feat:
        f = self.resolve(f)
        axes = sorted({a % f.rank for a in axes})
        if f.batch in axes:
            raise ConvertError(f"{op} over the batch axis mixes the batch (one pixel's value would depend on others)")
        keep = [a for a in range(f.rank) if a not in axes]
        moved = np.transpose(f.lanes, keep + axes)
        groups = int(np.prod([f.shape[a] for a in keep]))
        out = self._emit("reduce", moved, {"op": op, "groups": groups}, groups)
        kept_shape = [f.shape[a] for a in keep]
        lanes = out.reshape(kept_shape)
        if keepdim:
            lanes = lanes.reshape([1 if a in axes else f.shape[a] for a in range(f.rank)])
            return Feat(lanes, f.batch)
        return Feat(lanes, keep.index(f.batch))

    def layer_norm(self, f: Feat, dims: int, weight, bias, eps: float) -> Feat:
        """LayerNorm over the last ``dims`` axes."""
        f = self.resolve(f)
        if f.batch >= f.rank - dims:
            raise ConvertError("layer_norm over the batch axis mixes the batch")
        size = int(np.prod(f.shape[f.rank - dims:]))
        groups = f.lanes.size // size
        tensors = {}
        if weight is not None or bias is not None:
            tensors["weight"] = np.ones(size) if weight is None else np.asarray(weight, np.float32).reshape(-1)
            tensors["bias"] = np.zeros(size) if bias is None else np.asarray(bias, np.float32).reshape(-1)
        out = self._emit("layer_norm", f.lanes, {"eps": float(eps), "groups": groups, "affine": bool(tensors)},
                         f.lanes.size, tensors)
        return Feat(out.reshape(f.shape), f.batch)

    def lookup(self, coords: Feat, cells: np.ndarray) -> np.ndarray:
        """One multilinear lookup per position of ``coords`` (its last axis the d coordinates in
        [0, 1], x fastest) into ``cells`` [N_{d-1}..N_0, C]; returns lanes [positions..., C] (batch
        axis kept at size 1)."""
        coords = self.resolve(coords)
        d, channels = coords.shape[-1], cells.shape[-1]
        resolution = [int(n) for n in reversed(cells.shape[:-1])]
        points = coords.lanes.reshape(-1, d)
        out = np.zeros((len(points), channels), np.int64)
        for p, lanes in enumerate(points):
            for c0 in range(0, channels, 64):   # a lookup array holds at most 64 channels
                part = cells[..., c0:c0 + 64]
                out[p, c0:c0 + part.shape[-1]] = self._emit(
                    "lookup_array", lanes, {"resolution": resolution, "channels": int(part.shape[-1]), "bits": 32,
                                            "baked": "none"}, part.shape[-1], {"cells": part})
        return out.reshape(*coords.shape[:-1], channels)
