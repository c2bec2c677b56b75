"""Alpha, on a card in front of an opaque wall, its alpha (the base colour texture's alpha times the
factor's) read on the CPU from the file at the card's uv. MASK: where the alpha is below alphaCutoff
the pixel shows the wall behind, elsewhere the card itself, in the G-buffer every glTF pass starts
from, in the reference pass's colours and in the exported page. BLEND (depth peeling, front to back:
exact for every layer up to runtime/renderer.py BLEND_LAYERS, whatever order the file lists them in,
where a weighted blended order-independent sum would only approximate overlapping layers): the pixel
is alpha x the card + (1 - alpha) x the wall, on the desktop and in the page."""
from __future__ import annotations

import numpy as np
import pytest

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


def _file(path, mode: str, cutoff: float = CUTOFF, second_card: bool = False, second_first: bool = False,
          glass_alpha: float = 0.5):
    """The card (``mode``) at z = 0 before an opaque wall at z = -0.5; ``second_card``: another BLEND
    card, blue glass of ``glass_alpha``, half a unit nearer and shifted, listed before the first with
    ``second_first``."""
    b = GltfBuilder()
    tex = b.texture(b.image(_alpha()))
    front = b.material({"name": "card", "alphaMode": mode, **({"alphaCutoff": cutoff} if mode == "MASK" else {}),
                        "pbrMetallicRoughness": {"baseColorFactor": [1.0, 0.05, 0.05, 1.0], "metallicFactor": 0.0,
                                                 "baseColorTexture": {"index": tex}}})
    back = b.material({"name": "wall", "pbrMetallicRoughness": {"baseColorFactor": [0.05, 1.0, 0.05, 1.0],
                                                                 "metallicFactor": 0.0}})
    glass = b.material({"name": "glass", "alphaMode": "BLEND",
                        "pbrMetallicRoughness": {"baseColorFactor": [0.1, 0.2, 1.0, glass_alpha], "metallicFactor": 0.0}})
    nodes = [lambda: b.node(b.mesh([_card(0.0, front)], "card"), name="card")]
    if second_card:
        extra = lambda: b.node(b.mesh([_card(0.5, glass)], "glass"), translation=[0.5, 0.3, 0.0], name="glass")  # noqa: E731
        nodes = [extra, *nodes] if second_first else [*nodes, extra]
    for add in nodes:
        add()
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


@pytest.mark.parametrize("mode", ["MASK", "BLEND"])
@pytest.mark.parametrize("api", ["webgl2", "webgpu"])
def test_the_page_draws_the_card_as_inshade_render_does(gl, mode, api, tmp_path):
    """The exported page's G-buffer pass binds the material textures and cuts (MASK) or peels (BLEND)
    the same pixels: the wall shows through where the CPU reading says so, and the page is the
    desktop render's picture (within 3 levels away from edges: along the cards' outlines and the
    checker's, the two rasterisers and texture units put a few pixels on the other side, as they do
    for OPAQUE cards, and BLEND's filtered alpha differs by a few levels)."""
    from inshade.runtime.headless import render_scene
    from inshade.scene.description import load_scene
    from inshade.web.browser import Browser, serve, srgb8
    from inshade.web.export import export_web

    opaque_uv, _ = _draw(_file(tmp_path / "opaque.glb", "OPAQUE"))
    cut, kept = _cpu_reading(opaque_uv)
    path = _file(tmp_path / f"{mode}.glb", mode)
    export_web(path, tmp_path / "page", width=128, height=128, api=api)
    with Browser() as browser, serve(tmp_path / "page") as url:
        state = browser.open(url + "index.html")
        assert state["error"] is None, state
        assert browser.driver.execute_script("return window.inshade.api;") == api
        page = browser.canvas()
    rgb = page[::-1].astype(int)   # canvas rows (top first) -> the G-buffer's data rows
    assert (rgb[cut][:, 1] > rgb[cut][:, 0]).all() and (rgb[kept][:, 0] > rgb[kept][:, 1]).all()
    image, info = render_scene(load_scene(path), width=128, height=128)
    desktop = srgb8(image, tonemap=info["view"]["settings"]["tonemap"])[::-1].astype(int)
    diff = np.abs(rgb - desktop).max(-1)
    assert diff[cut | kept].max() <= 3, diff[cut | kept].max()
    # measured: MASK 20 pixels over 3 levels (all over 10: outline flips); BLEND 103 over 3, 10 over 10
    # (the checker's edges, where alpha blends between its two values, filtered by each texture unit)
    assert (diff > 3).mean() < 0.01, f"{(diff > 3).sum()} pixels differ by more than 3 levels"
    assert (diff > 10).mean() < 0.005, f"{(diff > 10).sum()} pixels differ by more than 10 levels"


def test_a_blend_card_is_laid_over_what_lies_behind_it(gl, tmp_path):
    """BLEND: where the card is, the picture is alpha x the card as drawn opaque + (1 - alpha) x the
    wall as drawn without the card, alpha the file's (read on the CPU); the G-buffer keeps the wall."""
    opaque_uv, card = _draw(_file(tmp_path / "opaque.glb", "OPAQUE"))
    _, wall = _draw(_file(tmp_path / "gone.glb", "MASK", cutoff=1.0))   # every texel's alpha is below 1
    blend_uv, image = _draw(_file(tmp_path / "blend.glb", "BLEND"))
    cut, kept = _cpu_reading(opaque_uv)
    inner = cut | kept
    # the checker's two values, as the image array holds them (8-bit 51 and 230 / 255, in half floats)
    alpha = np.float16(np.round(np.where(cut, 0.2, 0.9)[inner] * 255) / 255).astype(np.float64)
    rows = lambda a: a[::-1][..., :3][inner]   # noqa: E731 - image rows -> the G-buffer's data rows
    want = alpha[:, None] * rows(card) + (1 - alpha[:, None]) * rows(wall)
    np.testing.assert_allclose(rows(image), want, rtol=1e-4, atol=1e-5)
    assert (np.round(blend_uv[..., 2])[inner] == 1).all()   # the opaque layer under it is the wall
    assert np.abs(rows(image) - rows(card)).max() > 0.1 and np.abs(rows(image) - rows(wall)).max() > 0.1


def test_two_blend_cards_are_laid_in_depth_order(gl, tmp_path):
    """Two overlapping BLEND cards before the wall: the nearer (blue glass, alpha 0.5) is laid over
    the farther (the red card), whichever the file lists first: the card shows through the glass at
    half its strength, and the glass adds its blue."""
    _, behind = _draw(_file(tmp_path / "clear.glb", "BLEND", second_card=True, glass_alpha=0.0))
    a = _draw(_file(tmp_path / "ab.glb", "BLEND", second_card=True))[1]
    b = _draw(_file(tmp_path / "ba.glb", "BLEND", second_card=True, second_first=True))[1]
    np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-6)
    # the glass over the card's solid cells (alpha 0.9: strongly red behind it)
    under = (np.abs(a - behind)[..., :3].max(-1) > 1e-3) & (behind[..., 0] > 0.8)
    assert under.sum() > 100
    got, was = a[under], behind[under]
    assert (got[:, 0] > 0.45 * was[:, 0]).all() and (got[:, 0] < 0.6 * was[:, 0]).all()
    assert (got[:, 2] > was[:, 2] + 0.05).all()


def test_the_reader_says_how_see_through_materials_are_drawn(tmp_path):
    """Learnt materials learn colour, not alpha: every view draws MASK and BLEND with the file's own
    alpha, and the asset's notes (logged by every renderer of it) say so, naming the materials."""
    from inshade.geometry.gltf import load_gltf

    notes = load_gltf(_file(tmp_path / "blend.glb", "BLEND", second_card=True)).notes
    said = [n for n in notes if n.startswith("alpha: ")]
    assert len(said) == 1 and "card (BLEND), glass (BLEND)" in said[0] and "not their alpha" in said[0], notes
    assert not any(n.startswith("alpha: ") for n in load_gltf(_file(tmp_path / "opaque.glb", "OPAQUE")).notes)
