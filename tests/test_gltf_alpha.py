"""alphaMode MASK: a cut-out card in front of an opaque one. Where the card's alpha (its base colour
texture's alpha times the factor's, read on the CPU from the file at the card's uv) is below
alphaCutoff, the pixel shows the card behind; elsewhere the card itself, in the G-buffer every glTF
pass starts from, in the reference pass's colours and in the exported page."""
from __future__ import annotations

import numpy as np

from inshade.geometry.gltf_write import GltfBuilder, Primitive

CHECKS = 4          # checker squares per side of the card's alpha
SIDE = 64           # texels of the alpha image
CUTOFF = 0.4


def _card(z: float, material: int) -> Primitive:
    v = np.array([[-1, -1, z], [1, -1, z], [1, 1, z], [-1, 1, z]], np.float64)
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float64)
    n = np.tile([0.0, 0.0, 1.0], (4, 1))
    t = np.tile([1.0, 0.0, 0.0, 1.0], (4, 1))
    return Primitive(v, np.array([[0, 1, 2], [0, 2, 3]]), n, uv, t, material)


def _alpha() -> np.ndarray:
    """RGBA8 [SIDE, SIDE, 4], row 0 = the top (glTF v = 0): white, alpha a checkerboard of 0.2 / 0.9."""
    i = np.arange(SIDE) * CHECKS // SIDE
    a = np.where((i[:, None] + i[None, :]) % 2 == 0, 0.2, 0.9)
    out = np.full((SIDE, SIDE, 4), 255, np.uint8)
    out[..., 3] = np.round(a * 255)
    return out


def _file(path, mode: str):
    b = GltfBuilder()
    tex = b.texture(b.image(_alpha()))
    front = b.material({"name": "card", "alphaMode": mode, **({"alphaCutoff": CUTOFF} if mode == "MASK" else {}),
                        "pbrMetallicRoughness": {"baseColorFactor": [1.0, 0.05, 0.05, 1.0], "metallicFactor": 0.0,
                                                 "baseColorTexture": {"index": tex}}})
    back = b.material({"name": "wall", "pbrMetallicRoughness": {"baseColorFactor": [0.05, 1.0, 0.05, 1.0],
                                                                 "metallicFactor": 0.0}})
    b.node(b.mesh([_card(0.0, front)], "card"), name="card")
    b.node(b.mesh([_card(-0.5, back)], "wall"), scale=[1.5, 1.5, 1.0], name="wall")
    return b.write(path)


def _draw(path):
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import load_scene

    scene = load_scene(path)
    r = SceneRenderer(scene)
    try:
        r.render(scene.make_camera(), 128, 128)
        return r.gbuffer.read()[2], r.read()
    finally:
        r.release()


def _cpu_reading(opaque_uv):
    """(cut, kept) pixels of the G-buffer's rows: the card's alpha at the uv the opaque draw puts at
    each pixel (nearest texel, glTF v down), away from the checker's edges where the texture filter
    blends the two values, below / at or above the cutoff."""
    card = (opaque_uv[..., 3] > 0) & (np.abs(opaque_uv[..., 2] - 0.0) < 0.5)
    u, v = opaque_uv[..., 0], 1.0 - opaque_uv[..., 1]
    cell = np.stack([u, v], -1) * CHECKS
    inner = (np.abs(cell - np.round(cell)) > 0.1).all(-1) & card
    texel = np.clip((np.stack([v, u], -1) * SIDE).astype(int), 0, SIDE - 1)
    alpha = _alpha()[texel[..., 0], texel[..., 1], 3] / 255.0
    cut, kept = inner & (alpha < CUTOFF), inner & (alpha >= CUTOFF)
    assert cut.sum() > 300 and kept.sum() > 300
    return cut, kept


def test_a_mask_card_is_cut_out_where_its_alpha_is_below_the_cutoff(gl, tmp_path):
    opaque_uv, _ = _draw(_file(tmp_path / "opaque.glb", "OPAQUE"))
    masked_uv, image = _draw(_file(tmp_path / "mask.glb", "MASK"))
    cut, kept = _cpu_reading(opaque_uv)
    material = np.round(masked_uv[..., 2])
    assert (material[cut] == 1).all() and (material[kept] == 0).all()   # the wall behind / the card
    rgb = image[::-1][..., :3]   # image rows -> the G-buffer's data rows
    assert (rgb[cut][:, 1] > rgb[cut][:, 0]).all() and (rgb[kept][:, 0] > rgb[kept][:, 1]).all()


def test_the_page_cuts_a_mask_card_out_as_inshade_render_does(gl, tmp_path):
    """The exported page's G-buffer pass binds the material textures and cuts the same pixels: the
    wall shows through where the CPU reading says so, and the page is the desktop render's picture
    (within 3 levels away from edges: along the cards' outlines and the checker's, the two
    rasterisers and texture units put a few pixels on the other side, as they do for OPAQUE cards)."""
    from inshade.runtime.headless import render_scene
    from inshade.scene.description import load_scene
    from inshade.web.browser import Browser, serve, srgb8
    from inshade.web.export import export_web

    opaque_uv, _ = _draw(_file(tmp_path / "opaque.glb", "OPAQUE"))
    cut, kept = _cpu_reading(opaque_uv)
    path = _file(tmp_path / "mask.glb", "MASK")
    export_web(path, tmp_path / "page", width=128, height=128)
    with Browser() as browser, serve(tmp_path / "page") as url:
        state = browser.open(url + "index.html")
        assert state["error"] is None, state
        page = browser.canvas()
    rgb = page[::-1].astype(int)   # canvas rows (top first) -> the G-buffer's data rows
    assert (rgb[cut][:, 1] > rgb[cut][:, 0]).all() and (rgb[kept][:, 0] > rgb[kept][:, 1]).all()
    image, info = render_scene(load_scene(path), width=128, height=128)
    desktop = srgb8(image, tonemap=info["view"]["settings"]["tonemap"])[::-1].astype(int)
    diff = np.abs(rgb - desktop).max(-1)
    assert diff[cut | kept].max() <= 3, diff[cut | kept].max()
    assert (diff > 3).mean() < 0.005, f"{(diff > 3).sum()} pixels differ by more than 3 levels"


def test_a_blend_card_stays_whole(gl, tmp_path):
    """BLEND is drawn opaque (one surface per G-buffer pixel): the card covers what the OPAQUE card does."""
    opaque, _ = _draw(_file(tmp_path / "opaque.glb", "OPAQUE"))
    blend, _ = _draw(_file(tmp_path / "blend.glb", "BLEND"))
    card = (opaque[..., 3] > 0) & (np.round(opaque[..., 2]) == 0)
    assert card.sum() > 300 and np.array_equal(card, (blend[..., 3] > 0) & (np.round(blend[..., 2]) == 0))
