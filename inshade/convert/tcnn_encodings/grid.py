"""tiny-cuda-nn's grid encodings (encodings/grid.h: Grid, HashGrid, DenseGrid; TiledGrid is refused)
-> inshade's ``hash_grid`` / ``dense_grid`` components (table precision f16 for fp16 params)."""
from __future__ import annotations

import math

import numpy as np

from inshade.grid_layout import MAX_LEVELS, GridLayoutError, grid_levels, table_rows

from ..registry import tcnn_encoding
from ..tcnn_json import Reader
from .base import Encoding, lanes_of

GRID_HASHES = {"coherentprime": "coherent_prime", "prime": "prime", "reversedprime": "reversed_prime"}


class Grid(Encoding):
    """GridEncodingTemplated (encodings/grid.h): ``levels`` (inshade.grid_layout's GridLevel, the
    same rules) and the table of ``rows`` x ``features`` parameters. Padding lanes hold 0."""

    otype = "Grid"
    pad_value = 0.0

    def __init__(self, where, n_dims, r: Reader, default_type: str):
        super().__init__(where, n_dims)
        err = r.ctx.error
        self.features = r.uint("n_features_per_level", 2)
        if self.features not in (1, 2, 4, 8):
            raise err(f"{where}.n_features_per_level", f"{self.features}: must be 1, 2, 4 or 8")
        if r.has("n_features") or r.has("n_grid_features"):
            if r.has("n_levels"):
                raise err(f"{where}.n_levels", "may not be given with n_features (one determines the other)")
            key = "n_features" if r.has("n_features") else "n_grid_features"
            n_features = r.uint(key, None)
            if n_features % self.features:
                raise err(f"{where}.{key}", f"{n_features} is not a multiple of n_features_per_level "
                                            f"{self.features}")
            self.levels = n_features // self.features
        else:
            self.levels = r.uint("n_levels", 16)
        if not 1 <= self.levels <= MAX_LEVELS:
            raise err(f"{where}.n_levels", f"{self.levels}: inshade's grid components take 1..{MAX_LEVELS} levels")
        self.type = r.word("type", default_type, ("hash", "dense", "tiled", "tile"))
        if self.type in ("tiled", "tile"):
            raise err(f"{where}.type", "Tiled grids are not supported (inshade lowers Hash and Dense grids)")
        self.log2_hashmap_size = r.uint("log2_hashmap_size", 19)
        self.base_resolution = r.uint("base_resolution", 16)
        if r.has("per_level_scale"):
            self.per_level_scale = r.number("per_level_scale", None)
        elif self.type == "dense":
            self.per_level_scale = dense_default_scale(self.base_resolution, self.levels)
            if not np.isfinite(self.per_level_scale):
                raise err(f"{where}.per_level_scale", f"missing, and tiny-cuda-nn's Dense default "
                          f"exp(log(256 / base_resolution) / (n_levels - 1)) is undefined for n_levels "
                          f"{self.levels}: give it")
        else:
            self.per_level_scale = 2.0
        interpolation = r.word("interpolation", "Linear", ("nearest", "linear", "smoothstep"))
        if interpolation != "linear":
            raise err(f"{where}.interpolation", f"{r.obj['interpolation']}: inshade lowers Linear interpolation "
                                                f"only")
        self.hash = r.word("hash", "CoherentPrime", ("coherentprime", "prime", "reversedprime", "rng", "baseconvert"))
        if self.hash not in GRID_HASHES:
            raise err(f"{where}.hash", f"{r.obj['hash']}: inshade lowers CoherentPrime, Prime and ReversedPrime")
        if r.boolean("fixed_point_pos", False):
            raise err(f"{where}.fixed_point_pos", "true is not supported (its fixed-point positions change the "
                                                  "forward pass of tiny-cuda-nn's fused kernel)")
        # read for the record only: it changes the backward pass (kernel_grid_backward), not the forward
        self.stochastic_interpolation = r.boolean("stochastic_interpolation", False)
        if n_dims not in (2, 3):
            raise err(where, f"a grid over {n_dims} input lanes: inshade lowers 2D and 3D grids (tiny-cuda-nn "
                             f"also has 4D)")
        try:
            self.grid_levels = grid_levels(n_dims, self.levels, self.base_resolution, self.per_level_scale,
                                           self.log2_hashmap_size, self.type)
        except GridLayoutError as exc:
            raise err(where, str(exc)) from None
        self.alignment = self.features
        self.out = self.levels * self.features

    @property
    def rows(self) -> int:
        return table_rows(self.grid_levels)

    def n_params(self) -> int:
        return self.rows * self.features

    def params_text(self) -> str:
        return (f"{self.type} grid: {self.rows} table rows x {self.features} features over {self.levels} levels "
                f"(rows per level {', '.join(str(lv.rows) for lv in self.grid_levels)})")

    def resolved(self):
        out = {"otype": "Grid", "type": self.type.capitalize(), "n_levels": self.levels,
               "n_features_per_level": self.features, "base_resolution": self.base_resolution,
               "per_level_scale": self.per_level_scale, "interpolation": "Linear",
               "hash": {"coherentprime": "CoherentPrime", "prime": "Prime", "reversedprime": "ReversedPrime"}[
                   self.hash]}
        if self.type == "hash":
            out["log2_hashmap_size"] = self.log2_hashmap_size
        return out

    def lower(self, b, src, params, dtype):
        table = params.take(self.n_params(), (self.rows, self.features))
        common = {"levels": self.levels, "features": self.features, "base_resolution": self.base_resolution,
                  "per_level_scale": self.per_level_scale, "precision": "f16" if dtype == "float16" else "f32"}
        if self.type == "hash":
            kind = "hash_grid"
            common.update(log2_table_size=self.log2_hashmap_size, hash=GRID_HASHES[self.hash])
        else:
            kind = "dense_grid"
        node = b.node(kind, common, [src], {"table": table}, self.where)
        return self.with_padding(lanes_of(node, self.out))


def dense_default_scale(base_resolution: int, levels: int) -> float:
    """grid.h create_grid_encoding_templated_2: std::exp(std::log(256.0f / base) / (n_levels - 1)),
    all in float (each function rounded once to float32)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        log = np.float32(math.log(np.float32(256.0) / np.float32(base_resolution)))
        ratio = np.float32(log / np.float32(levels - 1)) if levels > 1 else np.float32(np.nan)
    return float(np.float32(math.exp(ratio))) if np.isfinite(ratio) else float("nan")



def _grid(default_type):
    return lambda where, n_dims, r: Grid(where, n_dims, r, default_type)


tcnn_encoding("Grid", "HashGrid")(_grid("hash"))
tcnn_encoding("TiledGrid")(_grid("tiled"))
tcnn_encoding("DenseGrid")(_grid("dense"))
