"""`inshade bench hash_grid --quick` on quick-preset assets built here (the trainer's quick preset, the
image and SDF within 16 KiB so a DI cascade of the image's bytes fits its 128² target): the JSON holds
every application's networks at equal bytes with their quality, bytes, plan-derived work per pixel
and frames, its GL measurements agree with the trainer's torch ones, the markdown names the renderer
and its tables, the suite's headlines read it; a missing asset is one error line (speed itself is
never asserted: machines are shared and noisy)."""
from __future__ import annotations

import argparse
import json

import pytest

from inshade.techniques.hash_grid import bench
from inshade.techniques.hash_grid import train as hg

APPS = {"image": ["--budget-kb", "16"], "sdf": ["--budget-kb", "16"], "radiance_field": []}


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    from inshade.runtime.context import shared_context

    root = tmp_path_factory.mktemp("hash_grid_bench")
    for app, extra in APPS.items():
        assert hg.main([app, "--preset", "quick", *extra, "-o", str(root / app)]) == 0
    shared_context()
    out = root / "report"
    assert bench.main(["--quick", "--image", str(root / "image"), "--sdf", str(root / "sdf"),
                       "--radiance-field", str(root / "radiance_field"), "--out", str(out)]) == 0
    metrics = {app: json.loads((root / app / "metrics.json").read_text()) for app in APPS}
    return json.loads((out / "hash_grid.json").read_text()), (out / "hash_grid.md").read_text(), out, metrics


def _rows(result, app) -> dict:
    return {r["key"]: r for r in result["apps"][app]["rows"]}


def test_writes_three_files_naming_the_renderer(report):
    result, md, out, _ = report
    renderer = result["machine"]["gl_renderer"]
    assert renderer and f"GL_RENDERER: `{renderer}`" in md
    assert (out / "hash_grid.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert result["quick"] and result["timing"]["sizes"] == [64] and set(result["apps"]) == set(APPS)
    for heading in ("## Against the bars", "## Image", "## SDF", "## Radiance field", "## Bytes", "## Not compared"):
        assert heading in md, heading
    assert "| hash grid + MLP | " in md and "| MLP-only | " in md and "| DI cascade | " in md


def test_every_network_is_measured_at_equal_bytes(report):
    result, _, _, metrics = report
    for app in APPS:
        rows = _rows(result, app)
        ours = rows["hash_grid"]
        assert ours["bytes"] == metrics[app]["bytes"]
        for other in rows.values():
            # within the hash grid's bytes; below by what one step of width (4 lanes) or of N_p (8) takes
            assert 0.8 * ours["bytes"] <= other["bytes"] <= ours["bytes"], (app, other["name"])
            assert other["flops_per_pixel"] == round(other["plan"]["flops"] * other["evaluations_per_pixel"])
            assert other["fetches_per_pixel"] == round(other["plan"]["fetches"] * other["evaluations_per_pixel"])
            assert other["first_draw_s"] > 0
        assert ours["frames"]["64"]["ms_median"] > 0 and ours["frames"]["64"]["frames"] == 1
        assert ours["plan"]["fetches"] > 0 and rows["mlp"]["plan"]["fetches"] == 0   # the tables are texture fetches
        app_record = result["apps"][app]
        assert app_record["table_bytes"] == metrics[app]["encoding"]["table_bytes_fp16"]
        assert app_record["bytes_file"] > ours["bytes"] // 2      # fp16 tables stored as F16


def test_image_rows_are_gl_renders_at_native_size(report):
    result, _, _, metrics = report
    rows = _rows(result, "image")
    m = metrics["image"]
    # the GL render at native size against the torch twin's PSNR of the same bundle (trainer)
    assert rows["hash_grid"]["quality"]["psnr_srgb"] == pytest.approx(m["psnr_srgb"], abs=0.01)
    assert rows["hash_grid"]["quality"]["psnr_linear"] == pytest.approx(m["psnr_linear"], abs=0.01)
    assert rows["mlp"]["quality"] == {k: m["mlp_baseline"][k] for k in ("psnr_srgb", "psnr_linear")}
    assert "metrics.json mlp_baseline" in rows["mlp"]["quality_source"]
    assert rows["mlp"]["frames"]["64"]["ms_median"] > 0 and rows["mlp"]["evaluations_per_pixel"] == 1.0
    di = rows["di"]
    assert di["training"]["steps"] == 20 and 0 < di["quality"]["psnr_srgb"] < 60
    assert ("flip" in di["quality"]) == (result["flip"] == "available")
    assert result["apps"]["image"]["uncompressed_bytes"] == 128 * 128 * 3


def test_marched_fields_count_evaluations_and_project_the_mlp_frame(report):
    result, _, _, metrics = report
    for app in ("sdf", "radiance_field"):
        rows = _rows(result, app)
        ours, mlp = rows["hash_grid"], rows["mlp"]
        assert ours["evaluations_per_pixel"] > 1 and mlp["evaluations_per_pixel"] == ours["evaluations_per_pixel"]
        assert ours["evaluation"]["points"] == 8 ** 3 and ours["evaluation"]["ns_per_evaluation"] > 0
        ratio = mlp["evaluation"]["ns_per_evaluation"] / ours["evaluation"]["ns_per_evaluation"]
        assert mlp["cost_ratio"] == pytest.approx(ratio, abs=0.0051)   # recorded to 2 decimals
        extra_ms = 1e-6 * (mlp["evaluation"]["ns_per_evaluation"] - ours["evaluation"]["ns_per_evaluation"])
        assert mlp["frames"]["64"]["ms_projected"] == pytest.approx(
            ours["frames"]["64"]["ms_median"] + extra_ms * ours["evaluations_per_pixel"] * 64 ** 2, abs=0.1)
    sdf = _rows(result, "sdf")["hash_grid"]
    assert sdf["quality"]["surface_abs_mean_per_diagonal"] == metrics["sdf"]["surface_abs_mean_per_diagonal"]
    assert _rows(result, "sdf")["mlp"]["quality"] is None          # the quick preset measures no baseline
    rf, m = _rows(result, "radiance_field"), metrics["radiance_field"]
    # the shader's march of held-out view 0 against the trainer's torch march of it
    assert rf["hash_grid"]["quality"]["heldout_psnr_per_view"][0] == pytest.approx(m["heldout_psnr_per_view"][0], abs=0.05)
    assert rf["mlp"]["quality"] == {"heldout_psnr": m["mlp_baseline"]["heldout_psnr"]}
    assert set(result["apps"]["sdf"]["not_compared"]) == {"DI-SDF"}
    assert set(result["apps"]["radiance_field"]["not_compared"]) == {"DI radiance field"}


def test_suite_headlines_read_the_report(report):
    from inshade.bench import suite

    result = report[0]
    rows = suite.headlines("hash_grid", result)
    keys = [r["claim"] for r in rows]
    assert keys == ["image", "image_mlp", "sdf", "radiance_field", "radiance_field_mlp"]
    image = rows[0]
    assert image["ours_value"] == _rows(result, "image")["hash_grid"]["quality"]["psnr_srgb"]
    assert image["ours_over_paper"] == pytest.approx(image["ours_value"] / 38.0)
    gap = rows[1]["ours_value"]
    assert gap == pytest.approx(image["ours_value"] - _rows(result, "image")["mlp"]["quality"]["psnr_srgb"])


def test_a_missing_asset_is_one_error_line(tmp_path, capsys):
    missing = tmp_path / "nowhere"
    assert bench.main(["--quick", "--apps", "sdf", "--sdf", str(missing), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert err == (f"inshade: error: {missing}: no bundle.json (train it: inshade train hash_grid sdf --preset ship "
                   f"-o {missing})")
    assert bench.main(["--apps", "image,nope", "--out", str(tmp_path / "o")]) == 2
    assert "--apps: unknown application nope" in capsys.readouterr().err


def test_quick_fills_only_options_left_at_their_defaults():
    args = bench.add_arguments(argparse.ArgumentParser()).parse_args(["--quick", "--frames", "3"])
    apps, sizes = bench._checked(args)
    assert apps == ("image", "sdf", "radiance_field") and sizes == (64,)
    assert args.frames == 3 and args.di_steps == 20 and args.probe == 16
