"""Every shipped asset under the settings that change its shader, rendered small: the regression
record that a refactor must reproduce pixel for pixel (linear float32 read-back, bit-identical).

    python tests/shipped_renders.py            # (re)write tests/data/shipped_renders.npz (+ .json)
    python tests/shipped_renders.py --missing  # add the cases the record lacks (a new asset), keep the rest
    pytest tests/test_shipped_renders.py       # render again and compare

The record is keyed by the renderer that made it (shipped_renders.json: GL_RENDERER and
GL_VERSION). On that renderer a render must be bit-identical; on any other (a GPU, another Mesa)
the driver's own arithmetic differs, so it is held to MIN_PSNR_DB on the linear float read-back
instead. Rewrite the record only when a change is meant to alter the pixels, and say so in the
commit.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RECORD = Path(__file__).resolve().parent / "data" / "shipped_renders.npz"
MADE_BY = RECORD.with_suffix(".json")   # the renderer that wrote the record
MIN_PSNR_DB = 50.0   # another renderer's render against the record (linear float, peak max(1, |record|))
# One shipped asset per technique: what the slower paths (the window, the browser) open by default;
# INSHADE_SLOW=1 opens every one (test_shipped_renders draws every one headless through the same renderer).
ONE_PER_TECHNIQUE = ["appearance_prefilter_grove", "di_brdf_ggx", "di_footprint", "di_pbr_set_bricks",
                     "di_radiance_field_trinket", "di_sdf", "di_shading_bricks", "di_texture_astronaut",
                     "hash_grid_image", "neural_appearance_ceramic", "neural_image", "prt_mesh_texture",
                     "sdf_creature", "uvfree_material_fruit_balanced"]
FLOORS: dict[str, float] = {}   # a case's own PSNR floor where its program is less stable than that

# (asset, settings): each asset once at its defaults, plus the settings that select other shader paths.
CASES = [
    ("neural_image", {}),
    ("sdf_creature", {}), ("sdf_mechanical", {}), ("sdf_occlusion", {"sky": "sunset", "env_rotation": 90.0}),
    ("prt_creature", {}), ("prt_creature", {"shading": "glossy", "sky": "sunset", "env_rotation": 90.0}),
    ("prt_mechanical", {}), ("prt_neural_bunny", {"shading": "glossy"}),
    ("prt_mesh", {}), ("prt_mesh", {"shading": "glossy", "phong_exponent": 32.0}),
    ("prt_mesh_texture", {}), ("prt_mesh_texture", {"shading": "glossy"}), ("prt_plants", {"shading": "glossy"}),
    ("prt_atrium", {}), ("prt_atrium", {"shading": "glossy"}),
    ("di_texture_astronaut", {}), ("di_texture_astronaut", {"lut_filter": "fast"}), ("di_texture_astronaut_12x", {}),
    ("di_texture_chelsea", {}), ("di_texture_coffee", {}),
    ("di_pbr_set_bricks", {}), ("di_pbr_set_bricks", {"view": "split", "lights": 4}),
    ("di_pbr_set_bricks", {"view": "uncompressed"}),
    ("di_footprint", {}), ("di_footprint", {"mode": 1}), ("di_footprint", {"mode": 2}), ("di_footprint", {"mode": 3}),
    ("di_brdf_ggx", {}), ("di_brdf_disney", {}), ("di_brdf_disney", {"lut_filter": "fast"}),
    ("di_sdf", {}),
    ("di_shading_bricks", {}), ("di_shading_bricks", {"view": 2}), ("di_shading_bricks", {"view": 4}),
    ("di_shading_bricks", {"view": 5}),
    ("di_radiance_field_trinket", {}), ("di_radiance_field_trinket", {"view": "split"}),
    ("di_radiance_field_trinket", {"view": "error", "lut_filter": "fast"}),
    ("neural_appearance_ceramic", {}), ("neural_appearance_ceramic", {"view": "reference"}),
    ("neural_appearance_brushed_metal", {"view": "split", "lighting": "environment"}),
    ("uvfree_material_stump_high_quality", {}), ("uvfree_material_stump_low_balanced", {"view": "error"}),
    ("uvfree_material_rock_balanced", {"view": "decoded", "wireframe": "level", "wire_level": 2}),
    ("uvfree_material_fruit_balanced", {"view": "split", "channel": "normal"}),
    ("appearance_prefilter_grove", {}),
    ("hash_grid_radiance_field", {}), ("hash_grid_radiance_field", {"view": "error"}),
    ("hash_grid_radiance_field", {"view": "samples", "empty_space": "evaluate"}),
    ("hash_grid_image", {}), ("hash_grid_sdf", {}),
]


def key(asset: str, settings: dict) -> str:
    return asset + "".join(f"|{k}={v}" for k, v in sorted(settings.items()))


def renderer_of(ctx) -> dict:
    """What identifies a renderer's arithmetic: its GL_RENDERER and GL_VERSION strings."""
    return {"gl_renderer": ctx.info["GL_RENDERER"], "gl_version": ctx.info["GL_VERSION"]}


def psnr_db(image: np.ndarray, want: np.ndarray) -> float:
    """PSNR of a linear float render against the record's, the peak being max(1, |record|)."""
    mse = float(np.mean((image.astype(np.float64) - want) ** 2))
    peak = max(1.0, float(np.abs(want).max()))
    return float("inf") if mse == 0.0 else 10.0 * np.log10(peak * peak / mse)


def compare(name: str, image: np.ndarray, want: np.ndarray, same_renderer: bool) -> str:
    """Hold a render to the record: bit for bit where the record's renderer made it, else at the
    case's PSNR floor. Returns the comparison made, in words; raises AssertionError on a miss."""
    assert image.shape == want.shape, f"{name}: shape {image.shape}, the record's {want.shape}"
    if same_renderer:
        differ = int(np.sum(image != want))
        assert differ == 0, (f"{name}: {differ} values differ from the record (same renderer: bit-identical "
                             f"expected), max {np.abs(image.astype(np.float64) - want).max():.3g}")
        return "bit-identical (the record's renderer)"
    floor = FLOORS.get(name, MIN_PSNR_DB)
    db = psnr_db(image, want)
    assert db >= floor, f"{name}: {db:.1f} dB against the record, under {floor:.0f} dB (another renderer)"
    return f"{db:.1f} dB >= {floor:.0f} dB (another renderer than the record's)"


def size(scene_size) -> tuple[int, int]:
    """A quarter of the scene's own size, at least 16 pixels a side (keeps aspect and runs fast)."""
    return max(16, scene_size[0] // 4), max(16, scene_size[1] // 4)


def render_case(asset: str, settings: dict) -> np.ndarray:
    from inshade.runtime.headless import render_scene
    from inshade.scene.description import load_scene

    scene = load_scene(ROOT / "trained" / asset)
    w, h = size(scene.size)
    image, _ = render_scene(scene, width=w, height=h, settings=settings)
    return np.asarray(image, np.float32)


def main(argv=None) -> int:
    import json

    from inshade.files import atomic_write
    from inshade.runtime.context import shared_context

    argv = sys.argv[1:] if argv is None else argv
    made_by = renderer_of(shared_context())
    images = {}
    if "--missing" in argv:
        recorded = json.loads(MADE_BY.read_text())
        if recorded != made_by:
            print(f"the record was made by {recorded}, this is {made_by}: rewrite it whole", file=sys.stderr)
            return 2
        with np.load(RECORD) as data:
            images = {k: data[k] for k in data.files}
    for asset, settings in CASES:
        if key(asset, settings) in images:
            continue
        images[key(asset, settings)] = render_case(asset, settings)
        print(f"rendered {key(asset, settings)} {images[key(asset, settings)].shape}", file=sys.stderr)
    RECORD.parent.mkdir(parents=True, exist_ok=True)
    tmp = RECORD.with_name(RECORD.name + ".tmp.npz")
    np.savez_compressed(tmp, **images)
    tmp.replace(RECORD)
    atomic_write(MADE_BY, json.dumps(made_by, indent=1) + "\n")
    print(f"wrote {RECORD} and {MADE_BY.name} ({made_by['gl_renderer']})", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
