"""Compressed glTF files as real ones ship: the project's procedural assets compressed by glTF
Transform's CLI (npm ``@gltf-transform/cli``: Draco through draco3d, meshopt with its quantization
and octahedral filters) read by inshade's reader (DracoPy, meshoptimizer) exactly as glTF Transform
itself decodes them (``decompress.mjs`` writes the same file uncompressed), bit for bit, and drawn
with the same pixels."""
from __future__ import annotations

import json
import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest

from inshade.geometry import gltf_scenes
from inshade.geometry.gltf import GltfError, load_gltf
from inshade.geometry.mesh import mesh_uv

TOOLS = Path(__file__).resolve().parents[1] / "gltf_tools"
CODECS = {"draco": "KHR_draco_mesh_compression", "meshopt": "EXT_meshopt_compression"}


def _run(*args) -> None:
    assert (TOOLS / "node_modules").is_dir(), f"run: npm ci --prefix {TOOLS}"
    proc = subprocess.run(args, cwd=TOOLS, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """{(scene, codec): (compressed, the same decoded by glTF Transform)}."""
    folder = tmp_path_factory.mktemp("codecs")
    out = {}
    for scene, path in gltf_scenes.write_all(folder).items():
        for codec in CODECS:
            packed, plain = folder / f"{scene}_{codec}.glb", folder / f"{scene}_{codec}_plain.glb"
            _run(str(TOOLS / "node_modules" / ".bin" / "gltf-transform"), codec, str(path), str(packed))
            _run("node", "decompress.mjs", str(packed), str(plain))
            out[scene, codec] = (packed, plain)
    return out


def _json(path: Path) -> dict:
    raw = path.read_bytes()
    (size,) = struct.unpack_from("<I", raw, 12)
    return json.loads(raw[20:20 + size])


@pytest.mark.parametrize("codec", CODECS)
@pytest.mark.parametrize("scene", list(gltf_scenes.SCENES))
def test_a_compressed_file_reads_as_its_decoder_gives_it(files, scene, codec):
    packed, plain = files[scene, codec]
    assert CODECS[codec] in _json(packed)["extensionsRequired"]
    assert CODECS[codec] not in _json(plain).get("extensionsUsed", [])
    a, b = load_gltf(packed), load_gltf(plain)
    assert np.array_equal(a.mesh.vertices, b.mesh.vertices) and np.array_equal(a.mesh.faces, b.mesh.faces)
    assert np.array_equal(mesh_uv(a.mesh), mesh_uv(b.mesh))
    for name in ("normal", "tangent", "material"):
        assert np.array_equal(a.mesh.vertex_attributes[name], b.mesh.vertex_attributes[name]), name
    assert np.array_equal(a.face_material, b.face_material)
    assert len(a.images) == len(b.images) and all(np.array_equal(x, y) for x, y in zip(a.images, b.images))


@pytest.mark.parametrize("codec", CODECS)
def test_a_compressed_file_draws_what_its_decoded_copy_draws(gl, files, codec):
    from inshade.runtime.headless import render_scene
    from inshade.scene.description import load_scene

    packed, plain = files["showcase", codec]
    images = [render_scene(load_scene(p), width=48, height=48)[0] for p in (packed, plain)]
    assert np.array_equal(images[0], images[1]) and images[0][..., :3].std() > 0.01


def test_a_broken_bitstream_is_one_line(files, tmp_path):
    """A Draco stream cut short: the reader names the primitive's extension, not a traceback."""
    packed, _ = files["tiles_torus", "draco"]
    doc = _json(packed)
    raw = packed.read_bytes()
    (size,) = struct.unpack_from("<I", raw, 12)
    blob_at = 20 + size + 8
    view = doc["bufferViews"][doc["meshes"][0]["primitives"][0]["extensions"][CODECS["draco"]]["bufferView"]]
    start = blob_at + view.get("byteOffset", 0)
    broken = bytearray(raw)
    broken[start: start + view["byteLength"]] = bytes(view["byteLength"])   # zeros: not a Draco header
    path = tmp_path / "broken.glb"
    path.write_bytes(bytes(broken))
    with pytest.raises(GltfError, match=r"meshes\[0\]\.primitives\[0\]\.extensions\.KHR_draco_mesh_compression: "
                                        r"cannot decode the Draco bitstream"):
        load_gltf(path)


def test_a_missing_decoder_is_one_line_with_the_install(files, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "DracoPy", None)   # as if not installed: import fails
    with pytest.raises(GltfError, match=r"KHR_draco_mesh_compression needs DracoPy, which is not installed: "
                                        r"pip install 'inshade\[gltf\]'"):
        load_gltf(files["tiles_torus", "draco"][0])


def test_webp_textures_read_as_libwebp_decodes_them(tmp_path):
    """EXT_texture_webp (glTF Transform's `webp`, through sharp / libwebp): each texture's WebP image
    is read, RGBA as libwebp (Pillow) decodes its bytes, near the PNG it was made from (lossy)."""
    import io

    from PIL import Image

    source = gltf_scenes.write_all(tmp_path)["tiles_torus"]
    packed = tmp_path / "webp.glb"
    _run(str(TOOLS / "node_modules" / ".bin" / "gltf-transform"), "webp", str(source), str(packed))
    doc = _json(packed)
    assert doc["extensionsRequired"] == ["EXT_texture_webp"] and "source" not in doc["textures"][0]
    a, b = load_gltf(packed), load_gltf(source)
    raw = packed.read_bytes()
    (size,) = struct.unpack_from("<I", raw, 12)
    blob = raw[20 + size + 8:]
    decoded = []
    for view in (doc["bufferViews"][im["bufferView"]] for im in doc["images"]):
        data = blob[view.get("byteOffset", 0): view.get("byteOffset", 0) + view["byteLength"]]
        decoded.append(np.asarray(Image.open(io.BytesIO(data)).convert("RGBA")))
    assert len(a.images) == len(decoded)
    assert all(any(np.array_equal(image, d) for d in decoded) for image in a.images)
    for x, y in zip(a.images, b.images):   # both in the order the materials use them
        mse = np.mean((x.astype(np.float64) - y) ** 2)
        assert 10 * np.log10(255 ** 2 / mse) > 20


# Basis Universal's own measure on this image (skimage's astronaut, 128x128), as encoded below:
# ETC1S 25.8 dB, UASTC 31.3 dB; the floors leave a margin for encoder versions
KTX2_FLOOR_DB = {"etc1s": 24.0, "uastc": 29.0}


@pytest.mark.parametrize("codec", KTX2_FLOOR_DB)
def test_ktx2_textures_transcode_within_the_codecs_error(gl, codec, tmp_path):
    """KHR_texture_basisu: a KTX2 base colour (ETC1S or UASTC, encoded by basisu) reads exactly as
    the Basis transcoder three.js ships decodes it (ktx2_decode.mjs), near the image it was made
    from, and draws."""
    import alktx2
    from skimage import data

    from inshade.geometry.gltf_write import GltfBuilder
    from inshade.geometry.shapes import sphere
    from inshade.runtime.headless import render_scene
    from inshade.scene.description import load_scene

    rgb = data.astronaut()[::4, ::4]
    rgba = np.ascontiguousarray(np.dstack([rgb, np.full(rgb.shape[:2], 255, np.uint8)]))
    ktx2 = alktx2.encode_raw_rgba_to_ktx2(rgba.tobytes(), rgba.shape[1], rgba.shape[0], codec=codec, srgb=True,
                                          threads=1)
    b = GltfBuilder()
    tex = b.texture(b.encoded_image(ktx2, "image/ktx2"), extension="KHR_texture_basisu")
    mat = b.material({"pbrMetallicRoughness": {"baseColorTexture": {"index": tex}, "metallicFactor": 0.0}})
    b.node(b.mesh([gltf_scenes._primitive(sphere(1.0, 16), mat)], "ball"))
    path = b.write(tmp_path / "ball.glb")
    asset = load_gltf(path)
    (tmp_path / "ball.ktx2").write_bytes(ktx2)
    _run("node", "ktx2_decode.mjs", str(tmp_path / "ball.ktx2"), str(tmp_path / "ball.rgba"))
    raw = (tmp_path / "ball.rgba").read_bytes()
    w, h = np.frombuffer(raw[:8], "<u4")
    assert np.array_equal(asset.images[0], np.frombuffer(raw[8:], np.uint8).reshape(h, w, 4))
    mse = np.mean((asset.images[0].astype(np.float64) - rgba) ** 2)
    assert 10 * np.log10(255 ** 2 / mse) >= KTX2_FLOOR_DB[codec]
    image, _ = render_scene(load_scene(path), width=48, height=48)
    assert image[..., :3].std() > 0.01
