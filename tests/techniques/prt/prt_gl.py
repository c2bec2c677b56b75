"""What the prt tests read back from a rendered asset: per settings change, the picture and the first
G-buffer targets; and the environment's SH, the scene and the bundles the renderer drew with. Also the
settings the tests' scenes declare."""
from __future__ import annotations

# The prt programs' settings as the test scenes declare them (fixed test values, not the shipped ones).
PRT_SETTINGS = {
    "shading": {"type": "choice", "default": "diffuse", "choices": ["diffuse", "glossy"], "uniform": "u_shading"},
    "phong_exponent": {"type": "float", "default": 8.0, "min": 0.0, "max": 256.0, "uniform": "u_phong_exponent"},
    "albedo": {"type": "float", "default": 1.0, "min": 0.0, "max": 2.0, "uniform": "u_albedo"},
    "kd": {"type": "float", "default": 1.0, "min": 0.0, "max": 1.0, "uniform": "u_kd"},
    "ks": {"type": "float", "default": 0.5, "min": 0.0, "max": 1.0, "uniform": "u_ks"},
    "debug": {"type": "int", "default": 0, "min": 0, "max": 6, "uniform": "u_prt_debug"},
    "sky": {"type": "choice", "default": "noon", "choices": ["noon", "sunset", "studio"], "environment": "sky"},
    "env_rotation": {"type": "float", "default": 0.0, "min": -180.0, "max": 180.0, "environment": "rotation"},
}


def prt_settings(*names: str) -> dict:
    """The named entries of PRT_SETTINGS, in that order: the settings a test's scene lets it turn."""
    return {name: dict(PRT_SETTINGS[name]) for name in names}


def render_views(program_cache, folder, settings_seq, size: int, targets: int = 0):
    """([(image, *the first ``targets`` G-buffer arrays) per settings dict], environment SH, scene,
    bundles); images in image orientation, G-buffer arrays in data orientation."""
    from inshade.runtime.context import shared_context
    from inshade.runtime.render import read_rgba
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import load_scene

    scene = load_scene(folder)
    r = SceneRenderer(scene, shared_context(), cache=program_cache)
    out = []
    try:
        cam = scene.make_camera()
        for settings in settings_seq:
            for k, v in settings.items():
                r.set_setting(k, v)
            image = read_rgba(r.render_network(cam, size, size)).copy()
            out.append((image, *([a.copy() for a in r.gbuffer.read()[:targets]] if targets else [])))
        return out, r.environment_sh(), scene, r.bundles
    finally:
        r.release()


def render_with_gbuffer(gl, program_cache, folder, settings_seq, size: int, targets: int):
    """render_views without the bundles."""
    out, sh, scene, _ = render_views(program_cache, folder, settings_seq, size, targets)
    return out, sh, scene
