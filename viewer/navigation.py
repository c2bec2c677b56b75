"""Mouse and keyboard -> camera, one mapping for every camera kind (the app only forwards input).

| input                     | plane2d (2D field)      | orbit                | fly                        |
|---------------------------|-------------------------|----------------------|----------------------------|
| left drag                 | pan                     | orbit                | look                       |
| right / middle drag       | pan                     | pan                  | look                       |
| wheel                     | zoom about the cursor   | dolly                | speed x1.25 per notch      |
| W A S D / Q E (held)      | pan                     | pan                  | move / down, up            |
| F                         | frame (fit)             | frame the bounds     | frame the bounds           |
| Home                      | reset to the scene camera                                                  |
"""
from __future__ import annotations

import numpy as np

ZOOM_PER_NOTCH = 1.15


def drag(camera, dx: float, dy: float, width: int, height: int, button: int = 0) -> None:
    kind = camera.kind
    if kind == "plane2d":
        camera.pan(dx, dy, width, height)
    elif kind == "orbit":
        camera.orbit(dx, dy) if button == 0 else camera.pan(dx, dy, width, height)
    elif kind == "fly":
        camera.look(dx, dy)


def scroll(camera, notches: float, x: float, y: float, width: int, height: int) -> None:
    kind = camera.kind
    if kind == "plane2d":
        camera.zoom_at(ZOOM_PER_NOTCH ** notches, x, y, width, height)
    elif kind == "orbit":
        camera.zoom(ZOOM_PER_NOTCH ** -notches)
    elif kind == "fly":
        camera.speed = float(np.clip(camera.speed * 1.25 ** notches, 1e-3, 1e3))


def keys(camera, forward: float, right: float, up: float, dt: float, width: int, height: int) -> None:
    """Held movement keys: forward/right/up in -1..1 each, for ``dt`` seconds."""
    if not (forward or right or up):
        return
    kind = camera.kind
    if kind == "fly":
        camera.move(forward, right, up, dt)
    else:  # pan at half a view per second
        px = 0.5 * dt * min(width, height)
        camera.pan(-right * px, (forward + up) * px, width, height)


def frame(camera, bounds=None) -> None:
    if camera.kind == "plane2d":
        camera.frame()
    else:
        lo, hi = bounds if bounds is not None else ((-1.0, -1.0, -1.0), (1.0, 1.0, 1.0))
        camera.frame(lo, hi)
