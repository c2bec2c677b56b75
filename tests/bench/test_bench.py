"""`inshade bench mlp --quick`: it runs end to end, writes its three files, and the code it
timed matches torch (speed itself is never asserted: machines are shared and noisy)."""
import json

import matplotlib  # noqa: F401  (required by inshade[bench]; an ImportError here is a broken install)
import pytest
import torch  # noqa: F401


def test_bench_mlp_quick(tmp_path, gl):
    from inshade.bench import mlp

    out = tmp_path / "bench"
    assert mlp.main(["--quick", "--storage", "inline,ubo,texture,ssbo", "--out", str(out)]) == 0
    for name in ("mlp.json", "mlp.md", "mlp.png"):
        assert (out / name).stat().st_size > 0, name
    assert (out / "mlp.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    result = json.loads((out / "mlp.json").read_text())
    assert result["machine"]["gl_renderer"]
    assert result["sgemm"]["gflops"] > 0
    assert result["networks"], "no network was measured"
    for net in result["networks"]:
        assert net["torch_s"] > 0
        assert set(net["modes"]) == {"inline", "ubo", "texture"}
        for mode, r in net["modes"].items():
            assert r["max_error"] < 1e-4, (net["name"], mode, r["max_error"])
            assert r["seconds"] > 0 and r["compile_link_s"] >= 0 and r["first_draw_s"] > 0
    assert result["max_error"] < 1e-4
    for net in result["networks"]:   # onnxruntime and every language beyond OpenGL, on the same batch
        assert net["onnxruntime"]["seconds"] > 0 and net["onnxruntime"]["max_error"] < 1e-4
        timed = {(r["target"], r["storage"]) for r in net["targets"] if "seconds" in r}
        skipped = {(r["target"], r["storage"]): r["skipped"] for r in net["targets"] if "skipped" in r}
        assert timed | set(skipped) == {(t, s) for t in ("wgsl", "vulkan", "hlsl", "slang")
                                        for s in ("inline", "ubo", "texture", "ssbo")}   # ssbo: beyond OpenGL only
        assert not skipped, skipped
        for r in net["targets"]:
            if "seconds" in r:
                assert r["parity_ok"] and r["device"] and r["seconds"] > 0, r

    md = (out / "mlp.md").read_text()
    assert result["machine"]["gl_renderer"] in md
    assert "## Targets" in md and "| inline |" in md
    assert "## Beyond OpenGL, and onnxruntime" in md and "| wgsl | texture |" in md


def test_bench_mlp_arguments():
    from inshade.bench import mlp

    parser = mlp.build_parser()
    args = parser.parse_args(["--widths", "16,64", "--storage", "inline,auto", "--out", "x"])
    assert args.widths == [16, 64] and args.storage == ["inline", "auto"] and args.size == 512
    with pytest.raises(SystemExit):
        parser.parse_args(["--storage", "nope"])
    assert parser.parse_args(["--targets", "wgsl,hlsl"]).targets == ["wgsl", "hlsl"]
    assert parser.parse_args(["--targets", ""]).targets == []
    with pytest.raises(SystemExit):
        parser.parse_args(["--targets", "330"])     # OpenGL's GLSL is what the bench always times


def test_bench_startup_quick(tmp_path):
    """`inshade bench startup --quick`: a shipped asset rendered in fresh processes, cold per storage and
    warm; its three files, each run's wall time, first draw and plan."""
    import json

    from inshade.bench import startup

    out = tmp_path / "startup"
    assert startup.main(["--quick", "--out", str(out)]) == 0
    report = json.loads((out / "startup.json").read_text())
    (row,) = report["assets"]
    assert row["asset"] == "neural_image" and set(row["cold"]) == {"auto", "texture"} and set(row["warm"]) == {"auto"}
    for run in [*row["cold"].values(), *row["warm"].values()]:
        assert run["wall_s"] > 0 and run["first_draw_s"] is not None and run["renderer"], run
    assert "texture" in row["cold"]["texture"]["resolved"] and row["quickest_cold"] in ("auto", "texture")
    assert 0 < row["view"]["first_frame_s"] <= row["view"]["full_frame_s"], row["view"]   # the window, too
    assert "| neural_image |" in (out / "startup.md").read_text() and (out / "startup.png").stat().st_size
    assert startup.main(["trained/no_such_asset", "--out", str(out)]) == 2


def test_bench_precision_on_a_network_sdf(tmp_path):
    """`inshade bench precision` on a scene traced through a network SDF (a hash grid and a small layer):
    the SDF quantized beside the networks, the grid's u8 codes shrinking the bytes and the page, each
    precision rendered; the report written after each asset."""
    import json

    from inshade.bench import precision

    out = tmp_path / "precision"
    assert precision.main(["trained/hash_grid_sdf", "--size", "16", "--out", str(out)]) == 0
    report = json.loads((out / "precision.json").read_text())
    (row,) = report["assets"]
    assert row["asset"] == "hash_grid_sdf" and row["networks"] == 1 and report["measured"] == "1 of 1 assets"
    assert row["bytes"]["i8"] < 0.6 * row["bytes"]["f16"] < row["bytes"]["f32"]
    assert row["page_bytes"]["i8"] < row["page_bytes"]["f16"] <= row["page_bytes"]["f32"]
    assert row["render_psnr"]["f32"] == float("inf") and row["render_psnr"]["f16"] > 50, row["render_psnr"]
    assert "reference_psnr" not in row   # no reference image, no reference view
    assert "| hash_grid_sdf |" in (out / "precision.md").read_text()
