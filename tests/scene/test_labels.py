"""Scene labels (scene/labels.py): an overlay on the 8-bit PNG and the window, never in the float
image or the EXR, turned off by the built-in setting ``labels``."""
import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from inshade.scene.labels import active, labels_for_info, layout, parse_labels
from inshade.scene.description import SceneError, load_scene

ROOT = Path(__file__).resolve().parents[2]
GGX = ROOT / "trained" / "di_brdf_ggx"


def test_labels_parse_and_follow_the_settings():
    scene = load_scene(GGX)
    assert scene.settings["labels"].default is True and not scene.settings["labels"].exposed
    values = scene.default_settings()
    shown = active(scene.labels, values, "network")
    assert sorted(lab.text for lab in shown if lab.text) == ["analytic", "learned"]
    assert any(lab.line for lab in shown)                                  # the divider of view 2
    assert [lab.text for lab in active(scene.labels, {**values, "view": 0}, "network")] == ["analytic"]
    assert active(scene.labels, {**values, "labels": False}, "network") == []
    assert active(scene.labels, values, "error") == []                     # not a view of the scene pass
    assert scene.settings["labels"].check(0) is False                      # --set labels=0


@pytest.mark.parametrize("asset", ["di_brdf_ggx", "di_brdf_disney", "di_footprint", "di_pbr_set_bricks"])
def test_shipped_comparisons_are_labelled(asset):
    scene = load_scene(ROOT / "trained" / asset)
    assert active(scene.labels, scene.default_settings(), scene.display_mode)


def test_plane2d_labels_follow_the_field():
    scene = load_scene(GGX)
    (text,) = layout([lab for lab in scene.labels if lab.text == "learned"][:1], scene.make_camera(), 1024, 64)
    assert text[0] == "text" and text[1] == pytest.approx(768) and text[2] == pytest.approx(0.05 * 64)


@pytest.mark.parametrize("labels,match", [
    ({"text": "a"}, r"labels\[0\]\.at"),
    ({"text": "a", "at": [0, 0], "when": {"nope": 1}}, r"labels\[0\]\.when\.nope: no such setting"),
    ({"line": [[0, 0]]}, r"labels\[0\]\.line"),
    ({"text": "a", "at": [0, 0], "size": 3}, r"labels\[0\]\.size: unknown field"),
    ({"text": "a", "at": [0, 0], "modes": ["sideways"]}, r"labels\[0\]\.modes"),
])
def test_bad_labels_are_one_clear_error(tmp_path, labels, match):
    data = json.loads((GGX / "scene.json").read_text())
    data["labels"] = [labels]
    for name in ("bundle.json", "weights.safetensors"):
        (tmp_path / name).symlink_to(GGX / name)
    (tmp_path / "scene.json").write_text(json.dumps(data))
    with pytest.raises(SceneError, match=match):
        load_scene(tmp_path)


def test_labels_for_info_reads_the_scene_file():
    info = {"scene": {"path": str(GGX / "scene.json")}, "view": {"mode": "network", "settings": {"view": 2}}}
    assert len(labels_for_info(info)) == 3
    info["view"]["settings"]["labels"] = False
    assert labels_for_info(info) == []
    assert labels_for_info({"scene": {"path": None}, "view": {}}) == []


def test_render_png_labels_only_where_the_labels_are(gl, tmp_path):
    from inshade.cli import main
    from inshade.scene.image_io import read_exr

    for name, extra in (("on", []), ("off", ["--set", "labels=0"])):
        for suffix in ("png", "exr"):
            assert main(["-q", "render", str(GGX), "-o", str(tmp_path / f"{name}.{suffix}"), *extra]) == 0
    np.testing.assert_array_equal(read_exr(tmp_path / "on.exr"), read_exr(tmp_path / "off.exr"))
    on = np.asarray(Image.open(tmp_path / "on.png")).astype(np.int16)
    off = np.asarray(Image.open(tmp_path / "off.png")).astype(np.int16)
    assert on.shape == off.shape == (64, 1024, 4)
    changed = np.abs(on - off).max(axis=2) > 0
    ys, xs = np.nonzero(changed)
    assert changed.any()
    # the texts (top band, around u = 0.25 and 0.75) and the divider (x = 512), nothing else
    text = (ys < 20) & ((np.abs(xs - 256) < 60) | (np.abs(xs - 768) < 60))
    line = np.abs(xs - 512) <= 1
    assert (text | line).all()
    assert changed[:20, 196:316].any() and changed[:20, 708:828].any() and changed[:, 511:514].any(axis=1).mean() > 0.9
    record = json.loads((tmp_path / "off.png.json").read_text())
    assert record["view"]["settings"]["labels"] is False


def test_labels_setting_does_not_change_the_float_image(gl):
    from inshade.runtime.headless import render_scene

    a, _ = render_scene(GGX, width=256, height=16)
    b, _ = render_scene(GGX, width=256, height=16, settings={"labels": False})
    assert np.array_equal(a, b)


def _label_scenes():
    import json
    from pathlib import Path

    root = Path(__file__).resolve().parents[2] / "trained"
    return sorted(p.parent.name for p in root.glob("*/scene.json") if json.loads(p.read_text()).get("labels"))


@pytest.mark.parametrize("asset", _label_scenes())
def test_shipped_labels_fit_at_256(asset):
    """At 256x256 every combination of the settings a scene's labels depend on lays its texts out
    inside the picture and apart from each other (the size shrinks to fit)."""
    import itertools
    import json
    from pathlib import Path

    from inshade.scene.labels import MIN_FONT, active, fit_texts, font_size, layout, parse_labels
    from inshade.scene.description import load_scene

    folder = Path(__file__).resolve().parents[2] / "trained" / asset
    scene = load_scene(folder)
    labels = parse_labels(json.loads((folder / "scene.json").read_text())["labels"])
    names = sorted({n for lab in labels for n, _ in lab.when})
    choices = [sorted({v for lab in labels for n, vals in lab.when if n == name for v in vals}, key=str) for name in names]
    for combo in itertools.product(*choices):
        values = {**dict(zip(names, combo)), "labels": True}
        items = layout(active(labels, values, "final"), scene.make_camera(), 256, 256)
        font, placed = fit_texts(items, 256, 256, font_size(256, 256))
        boxes = [p[4] for p in placed]
        assert all(0 <= b[0] and b[2] <= 256 and 0 <= b[1] and b[3] <= 256 for b in boxes), (combo, boxes)
        assert all(not (a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3])
                   for i, a in enumerate(boxes) for b in boxes[i + 1:]), (combo, font.size, placed)
        assert font.size >= MIN_FONT


def test_split_views_say_which_side_is_which():
    import json
    from pathlib import Path

    root = Path(__file__).resolve().parents[2] / "trained"
    for path in root.glob("*/scene.json"):
        scene = json.loads(path.read_text())
        choices = scene.get("settings", {}).get("view", {}).get("choices", [])
        if "split" in choices:
            texts = [lab for lab in scene.get("labels", []) if "text" in lab and lab.get("when", {}).get("view") == "split"]
            assert len(texts) >= 2, f"{path.parent.name}: a split view without labels"
