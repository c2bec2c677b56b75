"""The network pass of a scene as the renderer draws it, read back with the environment's SH it was
lit with: what a test holds against the torch twin's picture."""
from __future__ import annotations


def network_view(gl, scene, size: int):
    """(RGBA float image [size, size, 4], environment SH) of ``scene``'s network pass from its camera."""
    from inshade.runtime.render import read_rgba
    from inshade.runtime.renderer import SceneRenderer

    r = SceneRenderer(scene, gl)
    try:
        r.render_network(scene.make_camera(), size, size)
        return read_rgba(r._targets["network"]), r.environment_sh()
    finally:
        r.release()
