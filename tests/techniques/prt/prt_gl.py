"""What the prt tests read back from a rendered asset: per settings change, the picture and the first
G-buffer targets; and the environment's SH the renderer lit it with."""
from __future__ import annotations


def render_with_gbuffer(gl, cache, folder, settings_seq, size: int, targets: int):
    """[(image, *the first ``targets`` G-buffer arrays) per settings dict], environment SH, scene."""
    from inshade.runtime.render import read_rgba
    from inshade.runtime.renderer import SceneRenderer
    from inshade.scene.description import load_scene

    scene = load_scene(folder)
    r = SceneRenderer(scene, gl, cache=cache)
    out = []
    try:
        cam = scene.make_camera()
        for settings in settings_seq:
            for k, v in settings.items():
                r.set_setting(k, v)
            image = read_rgba(r.render_network(cam, size, size)).copy()
            out.append((image, *[a.copy() for a in r.gbuffer.read()[:targets]]))
        sh = r.environment_sh()
    finally:
        r.release()
    return out, sh, scene
