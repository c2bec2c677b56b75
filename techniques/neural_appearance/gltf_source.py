"""A glTF file's material as the reference a neural material is trained on (``inshade train
neural_appearance --gltf FILE [--material INDEX]``).

The reference is the spec's BRDF with its clearcoat, sheen and anisotropy lobes (models/gltf_brdf.py,
the numpy twin of shaders/lib/gltf_brdf.glsl) at the material's channels (geometry/gltf_sample.py
``material_channels``), in the local frame lib/gltf_material.glsl ``gltf_surface`` builds: the
geometric frame (t, b, ng) of the G-buffer, the normal map giving the shading normal n, the
anisotropy direction projected off n giving (at, ab), the clearcoat normal map giving nc. Emission,
occlusion and alpha are no part of the BRDF: the pass takes them from the file (lib/na_gltf).

Texture space: the latents cover the material's uv bounding box (gltf_info.py), baked at the
run's resolution (``PARAMS`` per texel, row 0 = v = 0 of the box).

Targets need no gradients, so the BRDF is evaluated in numpy (float32) and handed back as a tensor.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from inshade.geometry.gltf import GltfError, copy_gltf, gltf_uv, load_gltf
from inshade.geometry.gltf_sample import material_channels, require_first_uv_set, sample_texture
from inshade.geometry.mesh import mesh_uv
from inshade.models import gltf_brdf

# per-texel parameters (the baked texture space); normals and the anisotropy direction in tangent space
PARAMS = ("base_r", "base_g", "base_b", "metallic", "roughness", "clearcoat", "clearcoat_roughness",
          "sheen_r", "sheen_g", "sheen_b", "sheen_roughness", "anisotropy",
          "normal_x", "normal_y", "normal_z", "direction_x", "direction_y",
          "coat_normal_x", "coat_normal_y", "coat_normal_z")
P = {name: i for i, name in enumerate(PARAMS)}
# lib/gltf_material.glsl MATERIAL_MIN_ROUGHNESS: the smoothest lobe the reference shades
MIN_ROUGHNESS = 0.02
# encoder inputs (encoder_levels): the parameters as decoded quantities, the normal's slopes widening
# the roughness of coarse levels (LEAN, as material.parameter_pyramid does for the layered materials)
ENCODER_LAYOUT = ("base_r", "base_g", "base_b", "metallic", "alpha", "clearcoat", "clearcoat_alpha",
                  "sheen_r", "sheen_g", "sheen_b", "sheen_roughness", "anisotropy", "cos_2phi", "sin_2phi",
                  "normal_x", "normal_y", "normal_z", "coat_normal_x", "coat_normal_y", "coat_normal_z")
SOURCE_FILE = "source"     # the asset's copy of the file: source.glb / source.gltf


def _unit(x: np.ndarray) -> np.ndarray:
    return x / np.sqrt(np.maximum((x * x).sum(-1, keepdims=True), 1e-30))


def _box(a: np.ndarray) -> np.ndarray:
    h, w = a.shape[:2]
    return 0.25 * (a[0:h:2, 0:w:2] + a[1:h:2, 0:w:2] + a[0:h:2, 1:w:2] + a[1:h:2, 1:w:2])


def _material_index(path: Path, asset, material: str | None) -> int:
    """``--material``: an index of a material the mesh draws; None: the one covering most faces."""
    counts = np.bincount(asset.face_material, minlength=len(asset.materials))
    if material is None:
        return int(np.argmax(counts))
    text = str(material).strip()
    if not text.isdigit() or int(text) >= len(asset.materials):
        raise ValueError(f"--material: with --gltf, a material index of {path.name} "
                         f"(0..{len(asset.materials) - 1}), got {material!r}")
    index = int(text)
    if counts[index] == 0:
        raise ValueError(f"--material: {path}: materials[{index}] ({asset.materials[index].name!r}) covers "
                         "no triangle of the default scene")
    return index


class GltfSource:
    """Material ``material`` (an index, or None) of the glTF file ``path``."""

    encoder_inputs = len(ENCODER_LAYOUT)

    def __init__(self, path, material: str | None = None):
        self.path = Path(path)
        self.asset = load_gltf(self.path)          # GltfError: FILE: FIELD: problem
        require_first_uv_set(self.asset)
        uv = mesh_uv(self.asset.mesh)
        if uv is None:
            raise GltfError(f"{self.path}: meshes: no primitive has TEXCOORD_0; a neural material is learnt "
                            "over the mesh's texture coordinates")
        self.index = _material_index(self.path, self.asset, material)
        self.material = self.asset.materials[self.index]
        faces = self.asset.mesh.faces[self.asset.face_material == self.index]
        used = uv[faces.reshape(-1)]
        self.uv_min, self.uv_max = used.min(0), used.max(0)
        if not np.all(self.uv_max - self.uv_min > 1e-6):
            raise GltfError(f"{self.path}: meshes: TEXCOORD_0 of materials[{self.index}] "
                            f"({self.material.name!r}) spans no area ({self.uv_min.tolist()} .. "
                            f"{self.uv_max.tolist()})")
        self.setting = str(self.index)
        self.name = f"{self.path.stem}:{self.index}"
        self.f0 = np.float32(gltf_brdf.ior_f0(self.material.ior))

    # the texture space ----------------------------------------------------------------------
    def texel_uv(self, size: int) -> np.ndarray:
        """[size * size, 2] mesh uv of the latents' texel centres, row-major from v = uv_min."""
        c = (np.arange(size, dtype=np.float64) + 0.5) / size
        u, v = np.meshgrid(c, c)
        unit = np.stack([u.reshape(-1), v.reshape(-1)], 1)
        return self.uv_min + unit * (self.uv_max - self.uv_min)

    def bake(self, size: int) -> np.ndarray:
        """[size, size, len(PARAMS)] float32 over the uv box, row 0 = v = uv_min."""
        return self.parameters(self.texel_uv(size)).reshape(size, size, len(PARAMS))

    def parameters(self, uv: np.ndarray) -> np.ndarray:
        """``PARAMS`` [N, len(PARAMS)] float32 at mesh uv [N, 2] (the file's textures at their base level)."""
        uv = np.asarray(uv, np.float64)
        ch = material_channels(self.asset, self.index, uv)
        coat = self.material.clearcoat_normal_texture
        if coat is None:
            nc = np.tile([0.0, 0.0, 1.0], (len(uv), 1))
        else:     # lib/gltf_material material_normal on the clearcoat slot
            nc = sample_texture(self.asset, coat, gltf_uv(uv))[:, :3] * 2.0 - 1.0
            nc[:, :2] *= coat.scale
            nc = _unit(nc)
        out = np.concatenate([
            ch["base_color"], ch["metallic"][:, None],
            np.clip(ch["roughness"], MIN_ROUGHNESS, 1.0)[:, None], ch["clearcoat"][:, None],
            np.clip(ch["clearcoat_roughness"], MIN_ROUGHNESS, 1.0)[:, None], ch["sheen_color"],
            ch["sheen_roughness"][:, None], ch["anisotropy"][:, None], ch["normal"], ch["anisotropy_direction"],
            nc], 1)
        return np.ascontiguousarray(out, np.float32)

    def encoder_levels(self, raw: np.ndarray, levels: int) -> list[np.ndarray]:
        """``ENCODER_LAYOUT`` per level: level 0 from the texels, coarser ones by 2x2 box filtering of
        quantities that average linearly (alpha^2, the doubled anisotropy angle, normal slopes and
        their second moments, which widen alpha as LEAN does)."""
        p = raw.astype(np.float64)
        n = _unit(p[..., P["normal_x"]:P["normal_z"] + 1])
        nz = np.maximum(n[..., 2], 1e-3)
        sx, sy = -n[..., 0] / nz, -n[..., 1] / nz
        phi = np.arctan2(p[..., P["direction_y"]], p[..., P["direction_x"]])
        alpha2 = p[..., P["roughness"]] ** 4
        m = np.concatenate([p[..., 0:4], alpha2[..., None], p[..., 5:6], (p[..., 6:7] ** 4),
                            p[..., 7:12], np.cos(2 * phi)[..., None], np.sin(2 * phi)[..., None],
                            np.stack([sx, sy, sx * sx, sx * sy, sy * sy], -1),
                            p[..., P["coat_normal_x"]:P["coat_normal_z"] + 1]], -1)

        def features(m):
            mx, my = m[..., 14], m[..., 15]
            var = np.maximum(m[..., 16] - mx * mx, 0.0) + np.maximum(m[..., 18] - my * my, 0.0)
            normal = _unit(np.stack([-mx, -my, np.ones_like(mx)], -1))
            return np.concatenate([m[..., 0:4], np.sqrt(m[..., 4:5] + var[..., None]), m[..., 5:6],
                                   np.sqrt(m[..., 6:7]), m[..., 7:14], normal, _unit(m[..., 19:22])],
                                  -1).astype(np.float32)

        out = [features(m)]
        for _ in range(levels - 1):
            m = _box(m)
            out.append(features(m))
        return out

    # the reference --------------------------------------------------------------------------
    def shading(self, params: np.ndarray) -> tuple:
        """(Shading, n, at, ab, nc) at filtered parameters [N, len(PARAMS)], local frame (z = ng)."""
        p = np.asarray(params, np.float32)
        count = len(p)
        n = _unit(p[:, P["normal_x"]:P["normal_z"] + 1])
        d = np.zeros((count, 3), np.float32)
        d[:, :2] = p[:, P["direction_x"]:P["direction_y"] + 1]
        at = _unit(d - n * (n * d).sum(-1, keepdims=True))
        ab = np.cross(n, at)
        nc = _unit(p[:, P["coat_normal_x"]:P["coat_normal_z"] + 1])
        s = gltf_brdf.Shading(p[:, 0:3], p[:, P["metallic"]], p[:, P["roughness"]], np.full(count, self.f0),
                              p[:, P["clearcoat"]], p[:, P["clearcoat_roughness"]], p[:, P["sheen_r"]:P["sheen_b"] + 1],
                              p[:, P["sheen_roughness"]], p[:, P["anisotropy"]])
        return s, n, at, ab, nc

    def reflectance(self, params: torch.Tensor, light: torch.Tensor, view: torch.Tensor) -> torch.Tensor:
        """f * |n.l| of the glTF BRDF (models/gltf_brdf.py ``brdf``) for the local directions."""
        shape = params.shape[:-1]
        p = params.detach().reshape(-1, params.shape[-1]).float().cpu().numpy()
        lt = light.detach().reshape(-1, 3).float().cpu().numpy()
        vt = view.detach().reshape(-1, 3).float().cpu().numpy()
        s, n, at, ab, nc = self.shading(p)
        f = gltf_brdf.brdf(s, n, at, ab, nc, vt, lt)
        f = np.where(((lt[:, 2] > 0) & (vt[:, 2] > 0))[:, None], np.nan_to_num(f, nan=0.0, posinf=0.0), 0.0)
        return torch.from_numpy(np.ascontiguousarray(f, np.float32)).to(params.device).reshape(*shape, 3)

    # the asset ------------------------------------------------------------------------------
    def source_name(self) -> str:
        return SOURCE_FILE + self.path.suffix.lower()

    def write_files(self, out: Path, raw: np.ndarray) -> None:
        """The file itself (byte-identical: the scene's mesh and the reference's materials) and
        gltf_material.json. A .gltf's external buffers and images are copied beside it."""
        from .gltf_info import INFO_FILE, write_info

        copy_gltf(self.path, out, SOURCE_FILE)
        write_info(out / INFO_FILE, source=self.source_name(), material=self.index, material_name=self.material.name,
                   uv_min=self.uv_min, uv_max=self.uv_max)

    def scene(self, out: Path) -> dict:
        from .gltf_scene import scene_description

        faces = self.asset.mesh.faces[self.asset.face_material == self.index]
        corners = self.asset.mesh.vertices[faces.reshape(-1)]
        return scene_description(out, self.source_name(), self.index, self.material.name,
                                 (corners.min(0), corners.max(0)))

    def render_metrics(self, out: Path, spp: int, decoders: tuple[int, ...]) -> dict:
        from .gltf_scene import render_metrics

        return render_metrics(out, self.index, spp, decoders)
