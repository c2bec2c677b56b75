"""Every technique that trains from a glTF file trains from a compressed one, as it trains from the
same file decoded: the procedural tiles torus (geometry/gltf_scenes.py) with its mesh under
KHR_draco_mesh_compression or EXT_meshopt_compression (glTF Transform's CLI, as test_gltf_codecs.py
makes them), or with its five textures as KHR_texture_basisu images (UASTC KTX2 through basisu, sRGB
for base colour and emission, linear for metallic-roughness, normal and occlusion; every other byte
of the file as it was), fed to uvfree_material, neural_appearance, di_pbr_set and prt (``--gltf``) and
appearance_prefilter (``--scene``), each at the reduced quick settings its own glTF test uses.

Each training: exit status 0; the asset folder carries the compressed file byte for byte as its
scene's mesh (the runtime reads it through the same decoders) and the scene loads; metrics.json names
the file trained on; every bundle loads; the key metrics are finite and clear floors (the technique's
own glTF test's; uvfree_material's, whose test trains 120 steps, measured here: ``TECHNIQUES``). Then
the same training on the file's decoded copy, written by an independent decoder (glTF Transform's
``decompress.mjs`` for Draco and meshopt, three.js's Basis transcoder ``ktx2_decode.mjs`` for each
KTX2 image, stored back as PNG): the key metrics are equal, to the last digit. The reader hands the
trainer the decoders' arrays bit for bit (test_gltf_codecs.py) and training is seeded and
deterministic on the CPU, so a difference would be a trainer reading something of the file besides
what ``load_gltf`` decodes.

The default run trains each technique from one compressed file, the codecs spread over them
(``CI``: the texture-learning uvfree_material and di_pbr_set take KTX2, the others a geometry codec),
and trains the decoded copy too where a training takes under ``CI_TWICE_S`` (not di_pbr_set's):
~45 s here. INSHADE_SLOW=1 runs every (technique, codec) pair, each with its decoded copy, and
compares each with the uncompressed torus's training: codecs quantise and reorder vertices (Draco,
meshopt) or move texels (KTX2: 27.9 dB on the normal map to 55.4 dB on the emission, against the
PNGs), which moves these short trainings' scores by up to 2 dB (``margin_db``).
"""
from __future__ import annotations

import io
import json
import math
import os
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import pytest
import torch

from inshade.geometry import gltf_scenes
from inshade.geometry.gltf import load_gltf
from test_gltf_codecs import CODECS, TOOLS, _json, _run

SLOW = bool(os.environ.get("INSHADE_SLOW"))
KTX2 = "KHR_texture_basisu"
ALL_CODECS = (*CODECS, "ktx2")
# each texture's UASTC decode (basisu's defaults) against its PNG, RGB: measured 27.9 dB (the normal map)
# to 55.4 dB (emission), 31.0 dB metallic-roughness, 36.8 dB base colour
KTX2_FLOOR_DB = 25.0


# --- the files ---------------------------------------------------------------------------------------

def _glb_parts(raw: bytes) -> tuple[dict, bytes]:
    (size,) = struct.unpack_from("<I", raw, 12)
    return json.loads(raw[20:20 + size]), raw[20 + size + 8:]


def _glb(doc: dict, blob: bytes) -> bytes:
    text = json.dumps(doc, separators=(",", ":"), sort_keys=True).encode()
    text += b" " * (-len(text) % 4)
    blob += b"\0" * (-len(blob) % 4)
    chunks = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(blob), 0x004E4942) + blob
    return struct.pack("<III", 0x46546C67, 2, 12 + len(chunks)) + chunks


def _retextured(raw: bytes, images: list[tuple[bytes, str]], extension: str | None) -> bytes:
    """The GLB with image i's bytes and mimeType ``images[i]``, the textures taking them through
    ``extension`` (required, no core fallback) if given; every other bufferView keeps its bytes."""
    doc, blob = _glb_parts(raw)
    views = [blob[v.get("byteOffset", 0): v.get("byteOffset", 0) + v["byteLength"]] for v in doc["bufferViews"]]
    for image, (payload, mime) in zip(doc["images"], images, strict=True):
        views[image["bufferView"]] = payload
        image["mimeType"] = mime
    if extension is not None:
        for texture in doc["textures"]:
            texture["extensions"] = {extension: {"source": texture.pop("source")}}
        doc["extensionsUsed"] = sorted({*doc.get("extensionsUsed", []), extension})
        doc["extensionsRequired"] = sorted({*doc.get("extensionsRequired", []), extension})
    out = bytearray()
    for view, payload in zip(doc["bufferViews"], views):
        out += b"\0" * (-len(out) % 4)
        view["byteOffset"], view["byteLength"] = len(out), len(payload)
        out += payload
    doc["buffers"][0]["byteLength"] = len(out) + (-len(out) % 4)
    return _glb(doc, bytes(out))


def _ktx2_files(plain: Path, folder: Path) -> tuple[Path, Path]:
    """(the torus with its PNGs re-encoded as UASTC KTX2, the same with PNGs of what three.js's Basis
    transcoder decodes from those KTX2 images)."""
    import alktx2
    from PIL import Image

    raw = plain.read_bytes()
    doc, blob = _glb_parts(raw)
    mat = doc["materials"][0]
    colour = {doc["textures"][info["index"]]["source"]
              for info in (mat["pbrMetallicRoughness"]["baseColorTexture"], mat["emissiveTexture"])}
    encoded, decoded = [], []
    for i, image in enumerate(doc["images"]):
        view = doc["bufferViews"][image["bufferView"]]
        png = blob[view.get("byteOffset", 0): view.get("byteOffset", 0) + view["byteLength"]]
        rgba = np.asarray(Image.open(io.BytesIO(png)).convert("RGBA"))
        ktx2 = alktx2.encode_raw_rgba_to_ktx2(rgba.tobytes(), rgba.shape[1], rgba.shape[0], codec="uastc",
                                              srgb=i in colour, threads=1)
        (folder / f"{i}.ktx2").write_bytes(ktx2)
        _run("node", "ktx2_decode.mjs", str(folder / f"{i}.ktx2"), str(folder / f"{i}.rgba"))
        data = (folder / f"{i}.rgba").read_bytes()
        w, h = np.frombuffer(data[:8], "<u4")
        back = io.BytesIO()
        Image.fromarray(np.frombuffer(data[8:], np.uint8).reshape(h, w, 4)).save(back, format="PNG")
        encoded.append((ktx2, "image/ktx2"))
        decoded.append((back.getvalue(), "image/png"))
    packed, copy = folder / "tiles_torus_ktx2.glb", folder / "tiles_torus_ktx2_decoded.glb"
    packed.write_bytes(_retextured(raw, encoded, KTX2))
    copy.write_bytes(_retextured(raw, decoded, None))
    return packed, copy


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[str, tuple[Path, Path]]:
    """{"plain": (the tiles torus, itself), codec: (the torus compressed, its decoded copy)}: Draco
    and meshopt decoded by glTF Transform (decompress.mjs), KTX2 by three.js's Basis transcoder."""
    folder = tmp_path_factory.mktemp("codec_files")
    plain = gltf_scenes.tiles_torus().write(folder / "tiles_torus.glb")
    out = {"plain": (plain, plain)}
    for codec in CODECS:
        packed, copy = folder / f"tiles_torus_{codec}.glb", folder / f"tiles_torus_{codec}_decoded.glb"
        _run(str(TOOLS / "node_modules" / ".bin" / "gltf-transform"), codec, str(plain), str(packed))
        _run("node", "decompress.mjs", str(packed), str(copy))
        assert CODECS[codec] in _json(packed)["extensionsRequired"]
        out[codec] = packed, copy
    out["ktx2"] = _ktx2_files(plain, folder)
    assert KTX2 in _json(out["ktx2"][0])["extensionsRequired"]
    a, b = load_gltf(out["ktx2"][0]), load_gltf(plain)      # the mesh untouched, the textures near
    assert np.array_equal(a.mesh.vertices, b.mesh.vertices) and np.array_equal(a.mesh.faces, b.mesh.faces)
    assert len(a.images) == len(b.images) == 5
    for x, y in zip(a.images, b.images):
        mse = np.mean((x[..., :3].astype(np.float64) - y[..., :3]) ** 2)
        assert 0 < mse and 10 * np.log10(255 ** 2 / mse) >= KTX2_FLOOR_DB
    return out


# --- the trainers, at their glTF tests' settings ---------------------------------------------------

def _one_thread(fn: Callable[[], int]) -> int:
    """Many small ops: one torch thread is faster on a shared 2-core machine (as the di_pbr_set and
    appearance_prefilter tests train)."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        return fn()
    finally:
        torch.set_num_threads(before)


def _uvfree_material(source: Path, out: Path) -> int:
    from inshade.techniques.uvfree_material.train import main    # test_uvfree_material_gltf.py

    return main(["--gltf", str(source), "--preset", "quick", "--steps", "30", "--no-preview", "--out", str(out)])


def _neural_appearance(source: Path, out: Path) -> int:
    from inshade.techniques.neural_appearance.train import main  # test_neural_appearance_gltf.py

    return main(["--gltf", str(source), "--preset", "quick", "--out", str(out), "--no-preview", "--render-spp", "2"])


def _di_pbr_set(source: Path, out: Path) -> int:
    from inshade import cli                                     # test_di_pbr_set_gltf.py

    return _one_thread(lambda: cli.main(["train", "di_pbr_set", "--gltf", str(source), "--size", "128",
                                         "--steps", "300", "--render", "128", "-o", str(out)]))


def _prt(source: Path, out: Path) -> int:
    from inshade.techniques.prt import train                    # test_prt_gltf.py

    return train.main(["--gltf", str(source), "--out", str(out), "--cache", str(out.parent / "cache"),
                       "--preset", "quick", "--width", "16", "--layers", "2", "--points", "1000", "--dirs", "16",
                       "--steps", "300", "--quality-views", "1", "--quality-size", "24", "--quality-dirs", "64",
                       "--device", "cpu"])


def _appearance_prefilter(source: Path, out: Path) -> int:
    from inshade.techniques.appearance_prefilter import train   # test_appearance_prefilter_scene.py

    return _one_thread(lambda: train.main([
        "--scene", str(source), "--out", str(out), "--cache", str(out.parent / "cache"), "--preset", "quick",
        "--width", "8", "--latent", "12", "--steps", "40", "--batch", "256", "--device", "cpu"]))


@dataclass(frozen=True)
class Technique:
    train: Callable[[Path, Path], int]
    bundles: tuple[str, ...]                    # the asset's bundle folders
    source: Callable[[dict], str]               # the file metrics.json names
    scores: Callable[[dict], dict[str, float]]  # key metrics (dB)
    floors: dict[str, float]                    # held by every file here (the technique's test's floors)
    margin_db: float                            # how far a codec may move a score from the uncompressed run's
    seconds: float                              # one training here (llvmpipe, 2 cores, Mesa's cache warm)


# Measured scores (uncompressed / Draco / meshopt / KTX2); a codec moves them as any change of the
# mesh's vertex order, quantisation or texels does at these short trainings
TECHNIQUES = {
    # render 11.1 / 9.1 / 11.0 / 11.1 dB (steps 0: 2.4 / 6.1 dB), base colour 12.9 / 14.9 / 12.9 / 12.9 dB
    "uvfree_material": Technique(
        _uvfree_material, ("material",), lambda m: m["gltf"],
        lambda m: {"render": m["render"]["render_psnr_vs_reference"],
                   "base_color": m["torch_quality"]["psnr_base_color"]},
        {"render": 8.0, "base_color": 11.0}, 3.0, 4),
    # test_neural_appearance_gltf.py's floors; lights 21.8 / 21.9 / 21.8 / 21.7, shaded 16.8 / 17.2 / 16.8 / 16.9 dB
    "neural_appearance": Technique(
        _neural_appearance, ("latents", "decoder_3x64", "decoder_2x32", "decoder_2x16", "sampler",
                             "sampler_isotropic"),
        lambda m: m["settings"]["gltf"],
        lambda m: {"lights": m["render"]["psnr_lights_2x32"], "shaded": m["render"]["psnr_shaded_2x32"]},
        {"lights": 20.0, "shaded": 15.5}, 1.0, 4),
    # test_di_pbr_set_gltf.py's floors; render 23.9 / 23.8 / 23.9 / 24.3, lanes 23.1 / 22.0 / 23.1 / 22.4 dB
    "di_pbr_set": Technique(
        _di_pbr_set, ("",), lambda m: m["settings"]["gltf"],
        lambda m: {"render": m["render"]["psnr_di_vs_reference"], "lanes": m["di_glsl_exact"]["psnr_all_lanes"]},
        {"render": 21.0, "lanes": 17.0}, 2.0, 12),
    # test_prt_gltf.py's floors; diffuse 45.1 / 44.8 / 43.7 / 45.2, glossy 36.9 / 36.3 / 36.4 / 36.9,
    # reference 17.0 dB for all
    "prt": Technique(
        _prt, ("transfer",), lambda m: m["command"].split("--gltf=")[1].split(" --")[0],
        lambda m: {"diffuse": m["quality"]["diffuse"]["psnr"], "glossy": m["quality"]["glossy"]["psnr"],
                   "reference": m["reference"]["psnr"]},
        {"diffuse": 42.0, "glossy": 33.0, "reference": 14.0}, 2.5, 3),
    # test_appearance_prefilter_scene.py's floor (not a quality bound); traced 10.8, glTF 11.3 dB for all
    "appearance_prefilter": Technique(
        _appearance_prefilter, ("",), lambda m: m["settings"]["scene"],
        lambda m: {"traced": m["reference"]["traced"]["psnr"], "gltf": m["reference"]["gltf"]["psnr"]},
        {"traced": 9.0, "gltf": 9.0}, 0.5, 3),
}

# the default run: one compressed file per technique, every codec used
CI = {"uvfree_material": "ktx2", "neural_appearance": "draco", "di_pbr_set": "ktx2", "prt": "meshopt",
      "appearance_prefilter": "draco"}
assert set(CI) == set(TECHNIQUES) and set(CI.values()) == set(ALL_CODECS)
CI_TWICE_S = 10     # the default run trains the decoded copy too where a training takes less than this

PAIRS = [pytest.param(t, c, id=f"{t}-{c}", marks=() if CI[t] == c else pytest.mark.skipif(
    not SLOW, reason=f"the default run trains {t} from {CI[t]} only; set INSHADE_SLOW=1"))
    for t in TECHNIQUES for c in ALL_CODECS]


def _train(technique: str, source: Path, out: Path) -> dict:
    assert TECHNIQUES[technique].train(source, out) == 0
    return json.loads((out / "metrics.json").read_text())


@pytest.fixture(scope="module")
def scores_of(tmp_path_factory):
    """scores_of(technique, file): the key metrics of the technique trained on the file (once a module)."""
    done = {}

    def get(technique: str, source: Path) -> dict[str, float]:
        if (technique, source) not in done:
            out = tmp_path_factory.mktemp(f"{technique}_{source.stem}") / technique
            done[technique, source] = TECHNIQUES[technique].scores(_train(technique, source, out))
        return done[technique, source]
    return get


@pytest.mark.parametrize("technique, codec", PAIRS)
def test_trains_from_a_compressed_file(technique, codec, files, scores_of, tmp_path):
    from inshade.bundle import load
    from inshade.scene.description import load_scene

    spec, (source, decoded), out = TECHNIQUES[technique], files[codec], tmp_path / technique
    metrics = _train(technique, source, out)
    assert spec.source(metrics) == str(source)
    assert (out / "source.glb").read_bytes() == source.read_bytes()       # the compressed file as it is
    assert load_scene(out).mesh.gltf is not None
    for folder in spec.bundles:
        load(out / folder)
    scores = spec.scores(metrics)
    print(f"{technique} from {codec}: {scores}")
    assert all(math.isfinite(v) for v in scores.values()), scores
    assert all(scores[k] >= floor for k, floor in spec.floors.items()), (scores, spec.floors)
    if SLOW or spec.seconds < CI_TWICE_S:          # the same arrays in: the same training out
        copy = scores_of(technique, decoded)
        assert scores == copy, (scores, copy)
    if SLOW:
        plain = scores_of(technique, files["plain"][0])
        assert all(abs(scores[k] - plain[k]) <= spec.margin_db for k in plain), (scores, plain)
