"""The UV-free material's procedural objects (techniques/uvfree_material/objects.py, procedural.py,
object_textures.py): deterministic meshes and textures, sane ranges, the low/high stump pair
sharing one texture set and uv layout, uv seams that weld into closed outward-wound surfaces, the
OBJ + PNG round trip through ``inshade.geometry.mesh.load_mesh``, and ``sample_textures`` against GL's own
lookup of the written PNGs as the renderer uploads them (``runtime/scene_inputs.py scene_texture``)."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from inshade.geometry.mesh import edge_defects, load_mesh, mesh_uv, vertex_tangents
from inshade.metrics import srgb_eotf, srgb_oetf
from inshade.techniques.uvfree_material.object_textures import read_textures, sample_textures, write_object
from inshade.techniques.uvfree_material.objects import (
    FILES, OBJECTS, TEXTURES, ObjectError, TexturedObject, make_object)
from inshade.techniques.uvfree_material.procedural import normal_from_height
from parity import parity_settings

RES = 64          # small textures: generation is then dominated by the (fixed-size) meshes
FACES = {"rock": (3000, 8000), "fruit": (3000, 8000), "stump_low": (1000, 2000), "stump_high": (10000, 20000)}


@pytest.fixture(scope="module")
def objects() -> dict:
    return {n: make_object(n, RES) for n in OBJECTS}


@pytest.fixture(scope="module")
def written(objects, tmp_path_factory) -> dict:
    root = tmp_path_factory.mktemp("uvfree_objects")
    return {n: (root / n, write_object(o, root / n)) for n, o in objects.items()}


def _welded(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """The mesh with vertices of exactly equal position merged (uv seams closed)."""
    uniq, inverse = np.unique(mesh.vertices, axis=0, return_inverse=True)
    return trimesh.Trimesh(uniq, inverse.reshape(-1)[mesh.faces], process=False)


# --- determinism, shapes, ranges --------------------------------------------------------------

def test_same_seed_gives_identical_arrays():
    for name in ("rock", "stump_low"):
        a, b, c = make_object(name, 16, seed=3), make_object(name, 16, seed=3), make_object(name, 16, seed=4)
        np.testing.assert_array_equal(a.mesh.vertices, b.mesh.vertices)
        np.testing.assert_array_equal(a.mesh.faces, b.mesh.faces)
        np.testing.assert_array_equal(mesh_uv(a.mesh), mesh_uv(b.mesh))
        for k in TEXTURES:
            np.testing.assert_array_equal(a.textures[k], b.textures[k])
        assert not np.array_equal(a.textures["albedo"], c.textures["albedo"]), f"{name}: seed has no effect"


@pytest.mark.parametrize("name", OBJECTS)
def test_textures_have_shape_range_and_8bit_values(objects, name):
    obj = objects[name]
    assert isinstance(obj, TexturedObject) and obj.name == name and set(obj.textures) == set(TEXTURES)
    for k, tex in obj.textures.items():
        assert tex.shape == (RES, RES, 3) and tex.dtype == np.float32, k
        assert tex.min() >= 0.0 and tex.max() <= 1.0, k
    # exactly what the PNGs hold: k / 255 (albedo after sRGB encoding)
    for k in ("normal", "rma"):
        scaled = obj.textures[k].astype(np.float64) * 255.0
        np.testing.assert_allclose(scaled, np.round(scaled), atol=1e-4, err_msg=k)
    encoded = srgb_oetf(obj.textures["albedo"]) * 255.0
    np.testing.assert_allclose(encoded, np.round(encoded), atol=1e-3)


def test_materials_vary_as_described(objects):
    for name, obj in objects.items():
        albedo, rma = obj.textures["albedo"], obj.textures["rma"]
        assert albedo.std(axis=(0, 1)).max() > 0.03, f"{name}: albedo nearly constant"
        assert np.ptp(rma[..., 0]) > 0.1 and np.ptp(rma[..., 2]) > 0.2, f"{name}: roughness/AO nearly constant"
    fruit_metal = objects["fruit"].textures["rma"][..., 1]
    assert fruit_metal.min() == 0.0 and fruit_metal.max() > 0.9
    assert 0.001 < (fruit_metal > 0.5).mean() < 0.1, "the label should be a small metallic patch"
    assert objects["rock"].textures["rma"][..., 1].mean() < 0.05, "the rock is mostly dielectric"
    assert objects["fruit"].textures["rma"][..., 0].mean() < objects["rock"].textures["rma"][..., 0].mean()


@pytest.mark.parametrize("name", OBJECTS)
def test_albedo_is_coherent_not_white_noise(name):
    """Neighbouring texels are much closer than random pairs of texels (at the default-like 256)."""
    albedo = make_object(name, 256).textures["albedo"].astype(np.float64)
    neighbours = np.abs(np.diff(albedo, axis=1)).mean()
    shuffled = albedo.reshape(-1, 3)[np.random.default_rng(0).permutation(256 * 256)]
    random_pairs = np.abs(np.diff(shuffled, axis=0)).mean()
    assert neighbours < 0.4 * random_pairs, f"{name}: neighbours {neighbours:.4f}, random pairs {random_pairs:.4f}"


@pytest.mark.parametrize("name", OBJECTS)
def test_normal_maps_decode_to_unit_outward_vectors(objects, name):
    n = objects[name].textures["normal"].astype(np.float64) * 2.0 - 1.0
    length = np.linalg.norm(n, axis=-1)
    # 8-bit storage moves each component by <= 0.5 / 255 * 2, the length by < sqrt(3) / 255
    assert np.abs(length - 1.0).max() < np.sqrt(3.0) / 255.0 + 1e-6
    assert n[..., 2].min() > 0.5, "tangent-space normals point out of the surface (+z)"
    assert n[..., :2].std() > 0.01, f"{name}: the normal map is flat"


@given(a=st.floats(-0.05, 0.05), b=st.floats(-0.05, 0.05), len_u=st.floats(0.5, 8.0), len_v=st.floats(0.5, 8.0),
       rows=st.sampled_from([32, 64]), cols=st.sampled_from([32, 64, 128]))
def test_normal_from_height_follows_the_uv_convention(a, b, len_u, len_v, rows, cols):
    """h = a sin(2 pi u) + b v^2 in image order: n = normalize(-h_u / len_u, -h_v / len_v, 1), so
    the normal leans towards +u where height falls with u and towards +v where it falls with v
    (interior rows: the top and bottom rows are one-sided)."""
    u = (np.arange(cols) + 0.5) / cols
    v = 1.0 - (np.arange(rows) + 0.5) / rows
    uu, vv = np.meshgrid(u, v)
    n = normal_from_height(a * np.sin(2.0 * np.pi * uu) + b * vv ** 2, len_u, len_v)
    # central differences: exact for v^2, sin's derivative scaled by sinc(2 pi / cols) (periodic wrap)
    h_u = a * 2.0 * np.pi * np.cos(2.0 * np.pi * uu) * np.sin(2.0 * np.pi / cols) / (2.0 * np.pi / cols)
    want = np.stack([-h_u / len_u, -2.0 * b * vv / len_v, np.ones_like(uu)], -1)
    want /= np.linalg.norm(want, axis=-1, keepdims=True)
    np.testing.assert_allclose(n[1:-1], want[1:-1], atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1.0, atol=1e-12)


# --- meshes -----------------------------------------------------------------------------------

@pytest.mark.parametrize("name", OBJECTS)
def test_face_counts_bounds_and_no_degenerate_faces(objects, name):
    mesh = objects[name].mesh
    lo, hi = FACES[name]
    assert lo <= len(mesh.faces) <= hi, f"{name}: {len(mesh.faces)} faces"
    v = np.asarray(mesh.vertices)
    assert np.linalg.norm(v, axis=1).max() < 1.0
    assert np.abs(0.5 * (v.min(0) + v.max(0))).max() < 0.06, "centred"
    assert mesh.area_faces.min() > 1e-6


@pytest.mark.parametrize("name", OBJECTS)
def test_seams_weld_into_a_closed_outward_right_handed_surface(objects, name):
    mesh = objects[name].mesh
    uv = mesh_uv(mesh)
    assert uv is not None and np.isfinite(uv).all()
    # a seam exists: some positions carry several uv
    _, inverse = np.unique(mesh.vertices, axis=0, return_inverse=True)
    assert len(np.unique(inverse)) < len(mesh.vertices), f"{name}: no uv seam"
    assert edge_defects(mesh)[0] > 0, "unwelded, the seam is open"
    welded = _welded(mesh)
    assert edge_defects(welded) == (0, 0), "welded by exact position, the surface is closed"
    assert welded.is_winding_consistent
    assert welded.volume > 0.1, "faces wound counter-clockwise seen from outside"
    # tangent = +u, bitangent = +v, normal out: right-handed everywhere
    tangents = vertex_tangents(mesh)
    assert (tangents[:, 3] == 1.0).all()


def test_stump_pair_is_one_object_at_two_densities(objects):
    low, high = objects["stump_low"], objects["stump_high"]
    for k in TEXTURES:
        np.testing.assert_array_equal(low.textures[k], high.textures[k])
    assert len(high.mesh.faces) > 8 * len(low.mesh.faces)
    # every low-poly vertex (uv and position) is a high-poly vertex: one surface, one uv layout
    def keys(obj):
        rows = np.concatenate([mesh_uv(obj.mesh), obj.mesh.vertices], 1)
        return {tuple(r) for r in np.round(rows, 9)}

    missing = keys(low) - keys(high)
    assert not missing, f"{len(missing)} low-poly vertices are not on the high-poly mesh, e.g. {next(iter(missing))}"


# --- files ------------------------------------------------------------------------------------

@pytest.mark.parametrize("name", OBJECTS)
def test_obj_round_trip_keeps_faces_order_and_uv(objects, written, name):
    folder, files = written[name]
    assert files == FILES and all((folder / f).is_file() for f in files.values())
    mesh = objects[name].mesh
    loaded = load_mesh(folder / files["mesh"])
    assert len(loaded.faces) == len(mesh.faces)
    np.testing.assert_allclose(loaded.vertices[loaded.faces], mesh.vertices[mesh.faces], atol=1e-8)
    np.testing.assert_allclose(mesh_uv(loaded)[loaded.faces], mesh_uv(mesh)[mesh.faces], atol=1e-8)
    back = read_textures(folder)
    for k in TEXTURES:
        np.testing.assert_array_equal(back[k], objects[name].textures[k], err_msg=k)


def test_written_files_are_byte_identical(objects, written, tmp_path):
    write_object(objects["fruit"], tmp_path)
    folder, files = written["fruit"]
    for f in files.values():
        assert (tmp_path / f).read_bytes() == (folder / f).read_bytes(), f
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(files.values()), "no temporaries left"


# --- sample_textures --------------------------------------------------------------------------

textures_strategy = st.tuples(st.integers(1, 9), st.integers(1, 9), st.integers(1, 4)).flatmap(
    lambda s: hnp.arrays(np.float32, s, elements=st.floats(0.0, 1.0, width=32)))


@given(tex=textures_strategy, data=st.data())
def test_sample_textures_hits_texels_at_their_centres(tex, data):
    h, w = tex.shape[:2]
    i = np.array(data.draw(st.lists(st.integers(0, h - 1), min_size=1, max_size=8), label="rows"))
    j = np.array(data.draw(st.lists(st.integers(0, w - 1), min_size=len(i), max_size=len(i)), label="cols"))
    uv = np.stack([(j + 0.5) / w, 1.0 - (i + 0.5) / h], 1)
    out = sample_textures({"t": tex}, uv)["t"]
    assert out.shape == (len(i), tex.shape[2]) and out.dtype == np.float32
    np.testing.assert_allclose(out, tex[i, j], atol=1e-6)


@given(tex=textures_strategy, uv=hnp.arrays(np.float64, (6, 2), elements=st.floats(-0.5, 1.5)))
def test_sample_textures_is_bilinear_with_clamp_to_edge(tex, uv):
    h, w = tex.shape[:2]
    out = sample_textures({"t": tex}, uv)["t"]
    np.testing.assert_allclose(out, sample_textures({"t": tex}, np.clip(uv, 0.0, 1.0))["t"], atol=1e-6)
    lo, hi = tex.reshape(-1, tex.shape[2]).min(0), tex.reshape(-1, tex.shape[2]).max(0)
    assert (out >= lo - 1e-6).all() and (out <= hi + 1e-6).all()
    if w > 1:   # halfway between the centres of texels (0, 0) and (0, 1): their mean
        mid = sample_textures({"t": tex}, np.array([[1.0 / w, 1.0 - 0.5 / h]]))["t"][0]
        np.testing.assert_allclose(mid, 0.5 * (tex[0, 0].astype(np.float64) + tex[0, 1]), atol=1e-6)


def _gl_lookup(gl, png, uvs: np.ndarray) -> np.ndarray:
    """GL's bilinear lookup (no mipmaps, clamp-to-edge) of a PNG uploaded as scenes upload it, at
    ``uvs`` [N, 2]: RGB as stored (k / 255, no colour decode)."""
    from inshade.runtime.programs import ProgramCache
    from inshade.runtime.render import FullscreenPass, float_target, read_rgba_raw, release_target, upload_float_texture
    from inshade.runtime.scene_inputs import scene_texture as _scene_texture
    from inshade.scene.description import SceneTexture

    tex = _scene_texture(gl, SceneTexture("u_tex", png, mipmaps=False, repeat=False))
    cache = ProgramCache(gl)
    p = FullscreenPass(gl, cache.get("common/fullscreen.vert", "passes/texture_mips_test.frag"))
    n = len(uvs)
    uv_tex = upload_float_texture(gl, np.concatenate([uvs, np.zeros((n, 2))], -1).reshape(1, n, 4))
    fbo = float_target(gl, n, 1, 2)
    try:
        gl.viewport = (0, 0, n, 1)
        p.render(fbo, uniforms={"u_level": 0}, textures={"u_tex": tex, "u_inputs": uv_tex})
        return read_rgba_raw(fbo, 1).reshape(n, 4)[:, :3].astype(np.float64)
    finally:
        release_target(fbo)
        uv_tex.release()
        tex.release()
        p.vao.release()
        cache.release()


@parity_settings(4)
@given(name=st.sampled_from(OBJECTS), seed=st.integers(0, 2 ** 31 - 1))
def test_gl_lookup_of_the_written_pngs_matches_sample_textures(gl, objects, written, name, seed):
    """The orientation contract: a GL texture() lookup at uv of a written PNG (uploaded by the
    renderer's scene-texture path) equals sample_textures at uv. Exactly at texel centres; elsewhere
    within hardware filtering's precision on 8-bit textures: weights with 8 fractional bits (an
    error up to 2 / 256 of the largest difference between neighbouring texels) and a result kept
    at 8 bits (llvmpipe filters RGBA8 in 8-bit fixed point: up to one step, 1 / 255). A flipped or
    shifted lookup is off by about a texel difference, tens of times more."""
    rng = np.random.default_rng(seed)
    textures = objects[name].textures
    folder, files = written[name]
    i, j = rng.integers(0, RES, 16), rng.integers(0, RES, 16)
    centres = np.stack([(j + 0.5) / RES, 1.0 - (i + 0.5) / RES], 1)
    anywhere = rng.uniform(-0.05, 1.05, (48, 2))
    uvs = np.concatenate([centres, anywhere])
    for k in TEXTURES:
        stored = srgb_oetf(textures[k]) if k == "albedo" else textures[k].astype(np.float64)   # the PNG's values
        got = _gl_lookup(gl, folder / files[k], uvs)
        np.testing.assert_allclose(got[:16], stored[i, j], atol=1e-6, err_msg=f"{name} {k} at texel centres")
        if k == "albedo":
            np.testing.assert_allclose(srgb_eotf(got[:16]), textures[k][i, j], atol=1e-6)
        want = sample_textures({k: stored}, uvs)[k].astype(np.float64)
        step = max(np.abs(np.diff(stored, axis=0)).max(), np.abs(np.diff(stored, axis=1)).max())
        np.testing.assert_allclose(got, want, atol=2.0 * step / 256.0 + 1.0 / 255.0 + 1e-6, err_msg=f"{name} {k}")


# --- bad input --------------------------------------------------------------------------------

@pytest.mark.parametrize("kwargs, field", [
    ({"name": "cube"}, "name: unknown object 'cube'"),
    ({"name": "rock", "resolution": 100}, "resolution: 100"),
    ({"name": "rock", "resolution": 4}, "resolution: 4"),
    ({"name": "rock", "resolution": True}, "resolution: True"),
    ({"name": "rock", "resolution": 64.0}, "resolution: 64.0"),
    ({"name": "rock", "seed": -1}, "seed: -1"),
])
def test_make_object_refuses_bad_arguments(kwargs, field):
    with pytest.raises(ObjectError, match=f"^{field}"):
        make_object(**kwargs)


def test_sample_textures_and_files_refuse_bad_input(objects, tmp_path):
    tex = {"t": np.zeros((4, 4, 3), np.float32)}
    with pytest.raises(ObjectError, match=r"^uv: expected \[N, 2\]"):
        sample_textures(tex, np.zeros(3))
    with pytest.raises(ObjectError, match="^uv: 1 rows are NaN"):
        sample_textures(tex, np.array([[0.5, np.nan], [0.1, 0.2]]))
    with pytest.raises(ObjectError, match=r"^textures\['bad'\]: expected \[H, W, C\]"):
        sample_textures({"bad": np.zeros((4, 4))}, np.zeros((1, 2)))
    rock = objects["rock"]
    with pytest.raises(ObjectError, match="^textures: missing rma"):
        write_object(TexturedObject("rock", rock.mesh, {k: rock.textures[k] for k in ("albedo", "normal")}), tmp_path)
    with pytest.raises(ObjectError, match="^mesh: has no per-vertex uv"):
        write_object(TexturedObject("rock", trimesh.Trimesh(rock.mesh.vertices, rock.mesh.faces, process=False),
                                    rock.textures), tmp_path)
    assert not any(tmp_path.iterdir()), "nothing written on refusal"
    with pytest.raises(ObjectError, match="^albedo: .* does not exist"):
        read_textures(tmp_path)
