"""A glTF file's materials: its textures (image, uv set, KHR_texture_transform, wrap modes) and the
metallic-roughness model with the KHR lobes this project shades (emissive strength, ior, clearcoat,
sheen, anisotropy); KHR_materials_pbrSpecularGlossiness converted to metallic-roughness per texel
(the Khronos converter's metallic solve), and the colour helpers that conversion uses.
"""
from __future__ import annotations

import math

import numpy as np

from .gltf_document import GltfDocument
from .gltf_types import ALPHA_MODES, SPECULAR_GLOSSINESS, WRAPS, Material, TextureRef, field_error, floats, unit


def texture(doc: GltfDocument, info, where: str, scale_key: str | None = None) -> TextureRef | None:
    """A textureInfo (``None`` when absent); ``scale_key`` names the slot's scalar (``scale``, ``strength``)."""
    if info is None:
        return None
    if not isinstance(info, dict):
        raise field_error(where, "must be a textureInfo object")
    tex = doc.entry("textures", info.get("index"), f"{where}.index")
    source = tex.get("source")
    for name in ("KHR_texture_basisu", "EXT_texture_webp"):   # an extension's image first, the core's the fallback
        ext = (tex.get("extensions") or {}).get(name)
        if isinstance(ext, dict) and "source" in ext:
            source = ext["source"]
            break
    if source is None:
        raise field_error(f"textures[{info['index']}].source", "missing (no image)")
    image = doc.image(source, f"textures[{info['index']}].source")
    wrap = ("repeat", "repeat")
    if "sampler" in tex:
        s = doc.entry("samplers", tex["sampler"], f"textures[{info['index']}].sampler")
        try:
            wrap = (WRAPS[s.get("wrapS", 10497)], WRAPS[s.get("wrapT", 10497)])
        except KeyError:
            raise field_error(f"samplers[{tex['sampler']}]", "wrapS/wrapT must be 33071, 33648 or 10497") from None
    texcoord = info.get("texCoord", 0)
    transform = np.eye(3)
    ext = (info.get("extensions") or {}).get("KHR_texture_transform")
    if ext is not None:
        transform = texture_transform(ext.get("offset", (0.0, 0.0)), ext.get("rotation", 0.0),
                                      ext.get("scale", (1.0, 1.0)))
        texcoord = ext.get("texCoord", texcoord)
    if not isinstance(texcoord, int) or texcoord < 0:
        raise field_error(f"{where}.texCoord", f"must be an int >= 0, got {texcoord!r}")
    scale = float(info.get(scale_key, 1.0)) if scale_key else 1.0
    return TextureRef(image, texcoord, transform, wrap, scale)


def material(doc: GltfDocument, index: int) -> Material:
    """``materials[index]`` with its textures (their images decoded into ``doc.images``)."""
    m = doc.entry("materials", index, "materials")
    w = f"materials[{index}]"
    ext = m.get("extensions") or {}
    pbr = m.get("pbrMetallicRoughness") or {}
    out = Material(name=str(m.get("name", f"material {index}")))
    out.base_color = floats(pbr.get("baseColorFactor", out.base_color), 4, f"{w}.pbrMetallicRoughness.baseColorFactor")
    out.base_color_texture = texture(doc, pbr.get("baseColorTexture"), f"{w}.pbrMetallicRoughness.baseColorTexture")
    out.metallic = unit(pbr.get("metallicFactor", 1.0), f"{w}.pbrMetallicRoughness.metallicFactor")
    out.roughness = unit(pbr.get("roughnessFactor", 1.0), f"{w}.pbrMetallicRoughness.roughnessFactor")
    out.metallic_roughness_texture = texture(doc, pbr.get("metallicRoughnessTexture"),
                                             f"{w}.pbrMetallicRoughness.metallicRoughnessTexture")
    out.normal_texture = texture(doc, m.get("normalTexture"), f"{w}.normalTexture", "scale")
    out.occlusion_texture = texture(doc, m.get("occlusionTexture"), f"{w}.occlusionTexture", "strength")
    strength = float((ext.get("KHR_materials_emissive_strength") or {}).get("emissiveStrength", 1.0))
    out.emissive = tuple(strength * c for c in floats(m.get("emissiveFactor", (0.0, 0.0, 0.0)), 3,
                                                        f"{w}.emissiveFactor"))
    out.emissive_texture = texture(doc, m.get("emissiveTexture"), f"{w}.emissiveTexture")
    out.alpha_mode = m.get("alphaMode", "OPAQUE")
    if out.alpha_mode not in ALPHA_MODES:
        raise field_error(f"{w}.alphaMode", f"must be one of {', '.join(ALPHA_MODES)}, got {out.alpha_mode!r}")
    out.alpha_cutoff = float(m.get("alphaCutoff", 0.5))
    out.double_sided = bool(m.get("doubleSided", False))
    _lobes(doc, out, ext, w)
    sg = ext.get(SPECULAR_GLOSSINESS)
    if sg is not None:
        _specular_glossiness(doc, out, sg, f"{w}.extensions.{SPECULAR_GLOSSINESS}")
    return out


def _lobes(doc: GltfDocument, out: Material, ext: dict, w: str) -> None:
    """The KHR_materials_* lobes on top of the core model: ior, clearcoat, sheen, anisotropy."""
    if "KHR_materials_ior" in ext:
        out.ior = float(ext["KHR_materials_ior"].get("ior", 1.5))
    cc = ext.get("KHR_materials_clearcoat")
    if cc is not None:
        e = f"{w}.extensions.KHR_materials_clearcoat"
        out.clearcoat = unit(cc.get("clearcoatFactor", 0.0), f"{e}.clearcoatFactor")
        out.clearcoat_texture = texture(doc, cc.get("clearcoatTexture"), f"{e}.clearcoatTexture")
        out.clearcoat_roughness = unit(cc.get("clearcoatRoughnessFactor", 0.0), f"{e}.clearcoatRoughnessFactor")
        out.clearcoat_roughness_texture = texture(doc, cc.get("clearcoatRoughnessTexture"),
                                                  f"{e}.clearcoatRoughnessTexture")
        out.clearcoat_normal_texture = texture(doc, cc.get("clearcoatNormalTexture"),
                                               f"{e}.clearcoatNormalTexture", "scale")
    sh = ext.get("KHR_materials_sheen")
    if sh is not None:
        e = f"{w}.extensions.KHR_materials_sheen"
        out.sheen_color = floats(sh.get("sheenColorFactor", (0.0, 0.0, 0.0)), 3, f"{e}.sheenColorFactor")
        out.sheen_color_texture = texture(doc, sh.get("sheenColorTexture"), f"{e}.sheenColorTexture")
        out.sheen_roughness = unit(sh.get("sheenRoughnessFactor", 0.0), f"{e}.sheenRoughnessFactor")
        out.sheen_roughness_texture = texture(doc, sh.get("sheenRoughnessTexture"), f"{e}.sheenRoughnessTexture")
    an = ext.get("KHR_materials_anisotropy")
    if an is not None:
        e = f"{w}.extensions.KHR_materials_anisotropy"
        out.anisotropy_strength = unit(an.get("anisotropyStrength", 0.0), f"{e}.anisotropyStrength")
        out.anisotropy_rotation = float(an.get("anisotropyRotation", 0.0))
        out.anisotropy_texture = texture(doc, an.get("anisotropyTexture"), f"{e}.anisotropyTexture")


def _specular_glossiness(doc: GltfDocument, out: Material, sg: dict, where: str) -> None:
    """Replace ``out``'s base colour and metallic-roughness with the conversion of ``sg``: factors alone
    convert once, textures per texel into two new images at the larger texture's size."""
    diffuse = np.array(floats(sg.get("diffuseFactor", (1.0, 1.0, 1.0, 1.0)), 4, f"{where}.diffuseFactor"))
    specular = np.array(floats(sg.get("specularFactor", (1.0, 1.0, 1.0)), 3, f"{where}.specularFactor"))
    gloss = unit(sg.get("glossinessFactor", 1.0), f"{where}.glossinessFactor")
    d_tex = texture(doc, sg.get("diffuseTexture"), f"{where}.diffuseTexture")
    s_tex = texture(doc, sg.get("specularGlossinessTexture"), f"{where}.specularGlossinessTexture")
    out.converted_from = SPECULAR_GLOSSINESS
    if d_tex is None and s_tex is None:
        base, metallic = specular_glossiness_to_metallic(diffuse[None, :3], specular[None])
        out.base_color = (*base[0].tolist(), float(diffuse[3]))
        out.metallic, out.roughness = float(metallic[0]), 1.0 - gloss
        doc.notes.append(f"{out.name}: {SPECULAR_GLOSSINESS} converted to metallic-roughness (approximate)")
        return
    ref = d_tex or s_tex
    for t in (d_tex, s_tex):
        if t is not None and (t.texcoord != ref.texcoord or not np.allclose(t.transform, ref.transform)):
            raise field_error(where, "diffuse and specular-glossiness textures with different uv sets or "
                              "transforms cannot be converted per texel")
    shape = max((doc.images[t.image].shape[:2] for t in (d_tex, s_tex) if t is not None),
                key=lambda s: s[0] * s[1])
    d = _resized(doc.images[d_tex.image], shape) if d_tex else np.full((*shape, 4), 255, np.uint8)
    s = _resized(doc.images[s_tex.image], shape) if s_tex else np.full((*shape, 4), 255, np.uint8)
    d_lin = srgb_to_linear(d[..., :3] / 255.0) * diffuse[:3]
    s_lin = srgb_to_linear(s[..., :3] / 255.0) * specular
    g = s[..., 3] / 255.0 * gloss
    base, metallic = specular_glossiness_to_metallic(d_lin.reshape(-1, 3), s_lin.reshape(-1, 3))
    base_img = np.concatenate([_to8(linear_to_srgb(base.reshape(*shape, 3))),
                               _to8(d[..., 3:] / 255.0 * diffuse[3])], -1)
    mr = np.stack([np.full(shape, 255, np.uint8), _to8(1.0 - g), _to8(metallic.reshape(shape)),
                   np.full(shape, 255, np.uint8)], -1)
    doc.images += [base_img, mr]
    n = len(doc.images)
    out.base_color, out.metallic, out.roughness = (1.0, 1.0, 1.0, 1.0), 1.0, 1.0
    out.base_color_texture = TextureRef(n - 2, ref.texcoord, ref.transform, ref.wrap)
    out.metallic_roughness_texture = TextureRef(n - 1, ref.texcoord, ref.transform, ref.wrap)
    doc.notes.append(f"{out.name}: {SPECULAR_GLOSSINESS} converted to metallic-roughness per texel "
                     "(approximate: the metallic solve of the Khronos converter)")


def texture_transform(offset, rotation: float, scale) -> np.ndarray:
    """KHR_texture_transform's matrix: translation * rotation * scale, on glTF uv (the spec's order)."""
    c, s = math.cos(rotation), math.sin(rotation)
    t = np.array([[1.0, 0.0, offset[0]], [0.0, 1.0, offset[1]], [0.0, 0.0, 1.0]])
    r = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    sc = np.diag([scale[0], scale[1], 1.0])
    return t @ r @ sc


# colour and conversion helpers ---------------------------------------------------------------------
def srgb_to_linear(c):
    c = np.asarray(c, np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(c):
    c = np.clip(np.asarray(c, np.float64), 0.0, 1.0)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * c ** (1 / 2.4) - 0.055)


def _to8(x) -> np.ndarray:
    return np.clip(np.rint(np.asarray(x, np.float64) * 255.0), 0, 255).astype(np.uint8)


def _resized(image: np.ndarray, shape) -> np.ndarray:
    if image.shape[:2] == tuple(shape):
        return image
    from PIL import Image

    return np.asarray(Image.fromarray(image).resize((shape[1], shape[0]), Image.Resampling.BILINEAR), np.uint8)


def specular_glossiness_to_metallic(diffuse: np.ndarray, specular: np.ndarray, eps: float = 1e-6):
    """(base colour [N, 3], metallic [N]) from linear diffuse and specular [N, 3]: the metallic
    solve of the Khronos glTF converters (perceived brightness; dielectric F0 = 0.04)."""
    def brightness(c):
        return np.sqrt(0.299 * c[:, 0] ** 2 + 0.587 * c[:, 1] ** 2 + 0.114 * c[:, 2] ** 2)

    f0 = 0.04
    one_minus = 1.0 - specular.max(1)
    pd, ps = brightness(diffuse), brightness(specular)
    b = pd * one_minus / (1.0 - f0) + ps - 2.0 * f0
    c = f0 - ps
    metallic = np.where(ps < f0, 0.0, np.clip((-b + np.sqrt(np.maximum(b * b - 4 * f0 * c, 0.0))) / (2 * f0), 0, 1))
    from_diffuse = diffuse * (one_minus / (1.0 - f0) / np.maximum(1.0 - metallic, eps))[:, None]
    from_specular = (specular - f0 * (1.0 - metallic)[:, None]) / np.maximum(metallic, eps)[:, None]
    t = (metallic ** 2)[:, None]
    return np.clip(from_diffuse * (1 - t) + from_specular * t, 0.0, 1.0), metallic
