"""The scene.json parts both PBR-set assets share (the bricks torus, train.py; a glTF file's
material, gltf_asset.py): the point lights, the studio environment, the display modes, the settings
panel (lighting, the split view, the light count, the LUT path) and the requirements."""
from __future__ import annotations

from inshade.lit_settings import lit_settings
from inshade.scene.builder import choice_setting, display_modes, int_setting, lut_filter_setting, requires, sky


def lit_parts(lights: list, light_count: int, views, view_help: str, **settings) -> dict:
    """The scene's parts from ``lights`` to ``requires``: ``light_count`` of ``lights`` on at first, the
    ``views`` choice (split first) worded ``view_help``, and the asset's own ``settings`` before the
    LUT path."""
    return {
        "lights": lights,
        "environment": sky("studio", degree=3),
        "display": display_modes(),
        "settings": {
            **lit_settings("studio"),
            "view": choice_setting("split", views, view_help, uniform="u_pbr_view"),
            "lights": int_setting(light_count, 0, len(lights), "point lights", uniform="u_light_count"),
            **settings,
            "lut_filter": lut_filter_setting(),
        },
        "requires": requires(),
    }
