"""The hash-grid bench's claims (Instant NGP's, held to inshade's bars for its port) and the headline
rows `inshade bench suite` reads from its report; the report's tables and plot use them too."""
from __future__ import annotations

from inshade.bench.entry import Claim, claim_row

STEM = "hash_grid"

NGP = "Instant NGP (Müller et al. 2022)"
CLAIMS = {
    "image": Claim(NGP, "PSNR (sRGB) of the GL render of a >= 2K image at native size, network <= 1 MB",
                   "an image of 2048² or more at >= 38 dB within 1 MB (inshade's bar for its port)", 38.0),
    "sdf": Claim(NGP, "mean surface error of the SDF per bounding-box diagonal",
                 "<= 1e-3 of the bounding box (inshade's bar for its port)", 1e-3, higher_better=False),
    "radiance_field": Claim(NGP, "PSNR of the shader's march on held-out views",
                            ">= 30 dB on held-out views (inshade's bar for its port)", 30.0),
    "image_mlp": Claim(NGP, "image PSNR of the hash grid minus the MLP-only network's at equal bytes (dB)",
                       "the hash encoding beats a frequency-encoded MLP of the same size (> 0 dB)", 0.0),
    "sdf_mlp": Claim(NGP, "surface error of the MLP-only network / the hash grid's at equal bytes (> 1: hash grid "
                     "better)", "the hash encoding beats a frequency-encoded MLP of the same size (> 1)", 1.0),
    "radiance_field_mlp": Claim(NGP, "held-out PSNR of the hash grid minus the MLP-only network's at equal bytes "
                                "(dB)", "the hash encoding beats a frequency-encoded MLP of the same size (> 0 dB)", 0.0),
}
PRIMARY = {"image": "psnr_srgb", "sdf": "surface_abs_mean_per_diagonal", "radiance_field": "heldout_psnr"}


def _row(app: dict, key: str) -> dict | None:
    return next((r for r in app["rows"] if r.get("key") == key and r.get("quality")), None)


def headlines(r: dict) -> list[dict]:
    rows = []
    for name, app in r["apps"].items():
        metric = PRIMARY[name]
        ours, mlp = _row(app, "hash_grid"), _row(app, "mlp")
        value = ours["quality"][metric]
        where = f"{ours['bytes'] / 1e6:.2f} MB" + (f", {app['size']}² image" if name == "image" else "")
        text = f"{value:.3g} of the diagonal" if name == "sdf" else f"{value:.2f} dB"
        rows.append(claim_row(CLAIMS, STEM, name, f"{text} at {where}", value, name))
        if mlp is None or metric not in mlp["quality"]:
            continue
        theirs = mlp["quality"][metric]
        if name == "sdf":
            ratio = theirs / value
            rows.append(claim_row(CLAIMS, STEM, "sdf_mlp", f"{ratio:.1f}x: {value:.3g} vs MLP-only {theirs:.3g} at "
                                  f"{mlp['bytes'] / 1e6:.2f} MB", ratio, name))
        else:
            gap = value - theirs
            rows.append(claim_row(CLAIMS, STEM, f"{name}_mlp", f"{gap:+.2f} dB: {value:.2f} vs MLP-only {theirs:.2f} dB "
                                  f"at {mlp['bytes'] / 1e6:.2f} MB", gap, name))
    return rows
