"""The settings the teapot scene and a glTF file's scene share: how the neural material samples the
environment and decodes its latents, and the pyramid's debug views."""
from __future__ import annotations

from inshade.scene.builder import bool_setting, choice_setting, float_setting

from . import SAMPLING


def sampling_settings(sampling_help: str) -> dict:
    """BRDF sampling, MIS with the environment and the latents' filter."""
    return {
        "sampling": choice_setting("learned", SAMPLING, sampling_help, uniform="u_na_sampling"),
        "mis": bool_setting(True, "MIS with the environment", uniform="u_na_mis"),
        "latent_filter": choice_setting("exact", ["exact", "fast"],
                                        "latents: exact (texelFetch + fp32 mix) | fast (hardware bilinear)",
                                        codegen="latent_pyramid.filter"),
    }


def pyramid_settings() -> dict:
    """The pyramid's level bias and the error view's scale."""
    return {
        "level_bias": float_setting(0.0, -4.0, 4.0, "pyramid level bias", uniform="u_na_level_bias"),
        "error_scale": float_setting(4.0, 0.0, 64.0, "error scale", uniform="u_na_error_scale"),
    }
