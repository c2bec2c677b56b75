"""What the prt tests read back from a rendered asset: per settings change, the picture and the first
G-buffer targets; and the environment's SH, the scene and the bundles the renderer drew with."""
from __future__ import annotations


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
