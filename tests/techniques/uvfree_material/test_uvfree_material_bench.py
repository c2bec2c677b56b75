"""`inshade bench uvfree_material` on a tiny quick-trained asset (small renders, few rounds): the
three report files hold their tables, the bytes follow the codecs' block sizes and the training's
memory accounting, the rendered quality agrees with the torch evaluation, and a codec that cannot
run is an "unavailable" row. Speed is never asserted (shared, noisy machines)."""
import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from inshade.techniques.uvfree_material import bench, bench_measure

from parity import parity_settings
from uvfree_assets import train_quick

CODECS = "BC1,BC7,ASTC 4x4,ASTC 12x12"


@pytest.fixture(scope="module")
def asset(tmp_path_factory):
    return train_quick(tmp_path_factory.mktemp("uvf_bench") / "uvfree_material_rock_balanced", object_name="rock",
                       config="balanced", steps=60)


@pytest.fixture(scope="module")
def report(asset, tmp_path_factory):
    """The bench run once, with BC7 made unavailable (a codec that cannot run must not crash it)."""
    from inshade.bench.codecs import CodecError

    out = tmp_path_factory.mktemp("uvf_bench_out")
    real = bench_measure.roundtrip

    def roundtrip(codec, img8):
        if codec == "BC7":
            raise CodecError("etcpak not usable (test)")
        return real(codec, img8)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(bench_measure, "roundtrip", roundtrip)
        assert bench.main(["--assets", str(asset), "--out", str(out), "--quality-size", "48", "--width", "64",
                           "--height", "48", "--rounds", "3", "--warmup", "0", "--codecs", CODECS]) == 0
    return out


def test_bench_writes_json_markdown_plot(report, asset, gl):
    for suffix in ("json", "md", "png"):
        assert (report / f"uvfree_material.{suffix}").stat().st_size > 0, suffix
    assert (report / "uvfree_material.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not (report / "uvfree_material.partial.json").exists()
    r = json.loads((report / "uvfree_material.json").read_text())
    md = (report / "uvfree_material.md").read_text()
    a = r["assets"][asset.name]
    assert r["machine"]["gl_renderer"] in md
    for heading in ("## Targets", "## Summary", f"## {asset.name}", "### Quality", "### Memory", "### Baselines",
                    "### Decode cost"):
        assert heading in md, heading
    assert "| ASTC 4x4 |" in md and "| BC7 | unavailable |" in md
    assert [q["view"] for q in a["quality"]] == ["default", "close-up", "all"]
    assert r["targets"] == [] and "no high-poly asset" in md
    d = a["decode"]
    assert d["plan"]["fetches"] > 0 and d["plan"]["flops"] > 0
    assert set(d["ms"]) == {"decoded", "reference", "gbuffer"} and d["ms"]["decoded"]["n"] == 3
    assert d["decoded_over_reference"]["rounds"] == 3


def test_bench_memory_matches_training_accounting(report, asset):
    a = json.loads((report / "uvfree_material.json").read_text())["assets"][asset.name]
    trained = json.loads((asset / "metrics.json").read_text())["memory"]
    for key in ("features_bytes", "mlp_bytes", "topology_bytes", "reference_bytes", "rate_features_mlp", "rate_all"):
        assert a["memory"][key] == trained[key], key


def test_bench_codec_rows(report, asset):
    a = json.loads((report / "uvfree_material.json").read_text())["assets"][asset.name]
    rows = {b["codec"]: b for b in a["baselines"]}
    assert list(rows) == CODECS.split(",")
    assert rows["BC7"] == {"codec": "BC7", "available": False, "reason": "etcpak not usable (test)"}
    texels = a["memory"]["texture_size"][0] * a["memory"]["texture_size"][1]
    blocks12 = math.ceil(a["memory"]["texture_size"][0] / 12) * math.ceil(a["memory"]["texture_size"][1] / 12)
    # 3 maps: BC1 8 B per 4x4 block, ASTC 16 B per block of any footprint
    assert rows["BC1"]["bytes"] == 3 * texels // 2
    assert rows["ASTC 4x4"]["bytes"] == 3 * texels
    assert rows["ASTC 12x12"]["bytes"] == 3 * 16 * blocks12
    fine, coarse = (bench_measure.pooled(rows[c]["quality"]) for c in ("ASTC 4x4", "ASTC 12x12"))
    assert fine["albedo_psnr"] > coarse["albedo_psnr"] and fine["normal_mean_deg"] < coarse["normal_mean_deg"]
    e = a["equal_bytes"]["astc_features_mlp"]
    nb = a["memory"]["neural_bytes"]
    closest = min((rows[c] for c in ("ASTC 4x4", "ASTC 12x12")), key=lambda b: abs(b["bytes"] - nb))
    assert [c["codec"] for c in e["codecs"]] == [closest["codec"]]


def test_bench_quality_agrees_with_torch_evaluation(report, asset):
    """The shader's decoded channels read back as stored values (srgb_oetf of the channel view)
    score like the torch evaluation on area-sampled points: a missing decode of the display
    encoding would move albedo by several dB and the normal angle by degrees."""
    a = json.loads((report / "uvfree_material.json").read_text())["assets"][asset.name]
    torch_q = json.loads((asset / "metrics.json").read_text())["torch_quality"]
    q = bench_measure.pooled(a["quality"])
    assert abs(q["albedo_psnr"] - torch_q["psnr_albedo"]) < 1.0, (q, torch_q)
    assert abs(q["normal_mean_deg"] - torch_q["normal_mean_deg"]) < 0.35 * torch_q["normal_mean_deg"] + 0.2
    assert 0 < q["albedo_flip"] < 1 and q["normal_p95_deg"] >= q["normal_mean_deg"]


# --- metrics (no GL) ---------------------------------------------------------------------------

def _images(stored: dict, mask: np.ndarray) -> dict:
    """{(view, group): RGBA} as the channel views show ``stored`` values: srgb_eotf, alpha = coverage."""
    from inshade.metrics import srgb_eotf

    return {("default", g): np.concatenate([srgb_eotf(v) * mask[..., None], mask[..., None].astype(float)], -1)
            for g, v in stored.items()}


@parity_settings(8)
@given(seed=st.integers(0, 2**31 - 1), offset=st.floats(0.005, 0.2))
def test_group_metrics_psnr_of_a_known_offset(seed, offset):
    """Stored values shifted by ``offset`` on covered pixels: PSNR -20 log10(offset) per group;
    the background (alpha 0) never counts; identical normals give 0 degrees."""
    rng = np.random.default_rng(seed)
    mask = rng.random((24, 32)) < 0.6
    mask[0, 0] = True
    ref = {g: rng.uniform(0.3, 0.7, (24, 32, 3)) for g in bench_measure.GROUPS}
    for g in ("roughness", "metallic", "ao"):
        ref[g] = np.repeat(ref[g][..., :1], 3, -1)
    test = {g: v + (offset if g != "normal" else 0.0) for g, v in ref.items()}
    test = {g: np.where(mask[..., None], v, rng.random(v.shape)) for g, v in test.items()}   # background: noise
    row = bench_measure.group_metrics(_images(test, mask), _images(ref, mask), ("default",))
    want = -20 * math.log10(offset)
    for g in ("albedo", "shaded", "roughness", "metallic", "ao"):
        assert row[f"{g}_psnr"] == pytest.approx(want, abs=2e-3), g
    assert row["normal_mean_deg"] < 1e-3 and row["pixels"] == int(mask.sum())


@parity_settings(20)
@given(n=st.lists(st.floats(-1, 1), min_size=3, max_size=3), a=st.lists(st.floats(-1, 1), min_size=3, max_size=3),
       angle=st.floats(0.0, 179.0))
def test_normal_angles_recovers_a_rotation(n, a, angle):
    n, a = np.array(n), np.array(a)
    if np.linalg.norm(n) < 0.1 or np.linalg.norm(np.cross(n, a)) < 0.1:
        return
    n = n / np.linalg.norm(n)
    axis = np.cross(n, a) / np.linalg.norm(np.cross(n, a))   # perpendicular to n
    t = math.radians(angle)
    m = n * math.cos(t) + np.cross(axis, n) * math.sin(t)     # Rodrigues, axis . n = 0
    got = bench_measure.normal_angles((m * 0.5 + 0.5)[None], (n * 0.5 + 0.5)[None])
    assert got[0] == pytest.approx(angle, abs=1e-4)


def test_equal_bytes_targets_and_beating_astc():
    def row(codec, nbytes, db):
        return {"codec": codec, "available": True, "bytes": nbytes, "quality": [{"albedo_psnr": db}]}

    rows = [row("BC1", 100, 30.0), row("ASTC 6x6", 180, 33.0), row("ASTC 8x8", 220, 31.0),
            {"codec": "BC7", "available": False, "reason": "x"}]
    e = bench_measure.equal_bytes(200, 32.0, rows)
    assert [c["codec"] for c in e["codecs"]] == ["ASTC 6x6", "ASTC 8x8"]   # a tie: both
    assert [c["neural_beats"] for c in e["codecs"]] == [False, True] and not e["above_every_codec"]
    assert [c["codec"] for c in bench_measure.equal_bytes(90, 32.0, rows)["codecs"]] == ["BC1"]
    assert [c["codec"] for c in bench_measure.equal_bytes(90, 32.0, rows, astc_only=True)["codecs"]] == ["ASTC 6x6"]
    assert bench_measure.equal_bytes(900, "inf", rows)["above_every_codec"]
    assert bench_measure.equal_bytes(100, 30.0, rows[-1:]) is None

    def asset(config, db, rate, eb):
        return {"config": config, "quality": [{"albedo_psnr": db}], "equal_bytes": eb,
                "memory": {"rate_features_mlp": rate, "rate_all": rate + 0.5}}

    assets = {"uvfree_material_stump_high_memory": asset("memory", 32.5, 0.09, {
                  "astc_features_mlp": e, "astc_with_owner_tables": None}),
              "uvfree_material_stump_high_quality": asset("quality", 31.9, 0.33, {
                  "astc_features_mlp": None, "astc_with_owner_tables": None}),
              "uvfree_material_rock_memory": asset("memory", 40.0, 0.1, {
                  "astc_features_mlp": None, "astc_with_owner_tables": None})}
    t = bench_measure.targets(assets)
    assert [(x["config"], x["met"], x["met_with_owner_tables"]) for x in t] == [("memory", True, False),
                                                                              ("quality", False, False)]
    m = bench_measure.beats_astc(assets)
    assert m["astc_features_mlp"] == {"met": True, "assets": ["uvfree_material_stump_high_memory"]}
    assert m["astc_with_owner_tables"] == {"met": False, "assets": []}


@pytest.mark.parametrize("argv, field", [
    (["--codecs", "BC1,ETC9"], "--codecs"),
    (["--quality-size", "0"], "--quality-size"),
    (["--assets", "{missing}"], "no scene.json"),
])
def test_bench_bad_input_is_one_error_line(argv, field, tmp_path, capsys):
    argv = [a.format(missing=tmp_path / "nothing") for a in argv]
    assert bench.main([*argv, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("inshade: error:") and field in err[0], err


def test_bench_without_assets_names_the_option(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "trained" / "uvfree_material_rock_memory").mkdir(parents=True)   # still training: no scene.json
    assert bench.main(["--out", str(tmp_path / "out")]) == 2
    assert "--assets: no trained/uvfree_material_* folder with a scene.json" in capsys.readouterr().err


def test_default_assets_skip_folders_still_training(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for name in ("uvfree_material_b_quality", "uvfree_material_a_memory", "uvfree_material_c_balanced"):
        (tmp_path / "trained" / name).mkdir(parents=True)
    for name in ("uvfree_material_b_quality", "uvfree_material_a_memory"):
        (tmp_path / "trained" / name / "scene.json").write_text("{}")
    (tmp_path / "trained" / "neural_appearance_x").mkdir()
    folders, skipped = bench.asset_folders(None)
    assert [f.name for f in folders] == ["uvfree_material_a_memory", "uvfree_material_b_quality"]
    assert skipped == [str(Path("trained") / "uvfree_material_c_balanced")]


def test_codec_round_trips_are_shared_by_texture_content(asset, tmp_path, monkeypatch):
    """Configurations of one object hold the same textures: each map is encoded once per codec, and
    the copy's PNGs are the decoded images (the mesh, bundle and scene copied unchanged)."""
    from PIL import Image

    calls = []
    real = bench_measure.roundtrip
    monkeypatch.setattr(bench_measure, "roundtrip", lambda codec, img8: calls.append(codec) or real(codec, img8))
    memo = {}
    first = bench_measure.compressed_asset(asset, tmp_path / "a", "BC1", memo)
    second = bench_measure.compressed_asset(asset, tmp_path / "b", "BC1", memo)
    assert first == second and calls == ["BC1"] * 3
    for k in bench_measure.TEXTURES:
        a, b = (np.asarray(Image.open(tmp_path / x / f"{k}.png")) for x in "ab")
        orig = np.asarray(Image.open(asset / f"{k}.png").convert("RGB"))
        assert np.array_equal(a, b) and a.shape == orig.shape and not np.array_equal(a, orig)
    assert (tmp_path / "a" / "scene.json").read_bytes() == (asset / "scene.json").read_bytes()
    assert (tmp_path / "a" / "material" / "weights.safetensors").is_file()
