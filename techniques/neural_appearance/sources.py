"""What a neural material is trained from: a reference material behind one interface, so that the
training (train.py, data.py) never asks which kind it has.

- ``LayeredSource``: one of the technique's procedural layered materials (material.py, its torch
  twin reference.py), shown on the teapot with its GLSL twin (lib/na_reference);
- ``GltfSource`` (gltf_source.py): a glTF file's material under the spec's BRDF (models/gltf_brdf.py),
  shown on the file's own mesh next to lib/gltf_material's shading of it.

A source gives:

- ``name``: the asset's material name (bundle provenance); ``setting``: the ``--material`` value a run
  records (the layered material's name, or the glTF material's index);
- ``bake(size)``: its per-texel parameters over the latents' texture space, [size, size, C] float32,
  row 0 = v = 0 (what the targets filter, bilinear, repeat);
- ``encoder_inputs`` and ``encoder_levels(raw, levels)``: the phase-1 encoder's inputs per pyramid
  level (prefiltered for coarse levels);
- ``reflectance(params, light, view)``: f * cos [..., 3] at bilinear-filtered parameters, unit
  directions in the local frame of the geometric surface (z = normal), above its horizon;
- ``write_files(out, raw)`` and ``scene(out)``: what the asset's scene reads beside the bundles, and
  its scene.json;
- ``render_metrics(out, spp, decoders)``: quality measured through the GL runtime once the asset is written
  ({} where the technique's bench measures it instead).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from inshade.files import atomic_write


class LayeredSource:
    """A layered material description (materials/*.json or a file)."""

    def __init__(self, material: str):
        from .material import ENCODER_INPUTS, load_material

        self.material = load_material(material)
        self.name = self.setting = self.material.name
        self.encoder_inputs = ENCODER_INPUTS

    def bake(self, size: int) -> np.ndarray:
        from .material import bake_parameters

        return bake_parameters(self.material, size)

    def encoder_levels(self, raw: np.ndarray, levels: int) -> list[np.ndarray]:
        from .material import parameter_pyramid

        return parameter_pyramid(raw, levels, self.material)

    def reflectance(self, params: torch.Tensor, light: torch.Tensor, view: torch.Tensor) -> torch.Tensor:
        from .reference import reflectance

        return reflectance(params, light, view, self.material)

    def write_files(self, out: Path, raw: np.ndarray) -> None:
        """The parameter textures and the description (lib/na_reference's inputs)."""
        from .material import write_textures

        write_textures(self.material, raw.shape[0], out)
        atomic_write(out / "material.json", Path(self.material.path).read_bytes())

    def scene(self, out: Path) -> dict:
        from .data import scene_description

        return scene_description(self.material, out.name)

    def render_metrics(self, out: Path, spp: int, decoders: tuple[int, ...]) -> dict:
        return {}     # inshade bench neural_appearance measures the layered materials' renders


def open_source(material: str | None, gltf: str | None):
    """The reference a run trains on: ``gltf`` (a file) with ``material`` its material's index (None:
    the material covering most faces), else the layered ``material`` (None: ceramic)."""
    if gltf is not None:
        from .gltf_source import GltfSource

        return GltfSource(gltf, material)
    return LayeredSource("ceramic" if material is None else material)
