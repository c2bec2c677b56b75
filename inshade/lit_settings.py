"""Settings every lit scene (an SDF or a mesh under the SH environment) exposes, in scene.json form.

Shared by the asset builders of every lit technique; plain data, no runtime import."""
from __future__ import annotations


def lit_settings(sky: str = "noon") -> dict:
    """The settings every lit (SDF or mesh) scene exposes, in scene.json form: exposure, the sky
    preset (inshade.sh SKY_PRESETS) and its rotation. Asset builders add their own after these."""
    from inshade.sh import SKY_PRESETS

    return {
        "exposure": {"type": "float", "default": 1.0, "min": 0.0, "max": 8.0, "uniform": "u_exposure",
                     "label": "exposure"},
        "sky": {"type": "choice", "default": sky, "choices": list(SKY_PRESETS), "environment": "sky",
                "label": "environment"},
        "env_rotation": {"type": "float", "default": 0.0, "min": -180.0, "max": 180.0, "environment": "rotation",
                         "label": "env rotation (deg)"},
    }
