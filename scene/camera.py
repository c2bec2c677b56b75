"""Cameras as data: each kind turns its state into the uniforms a pass reads, and back into JSON.

- ``plane2d``: pan/zoom over a 2D field's unit square (uv (0,0) bottom-left). Uniform
  ``u_view = (offset.xy, scale.xy)`` with ``uv = offset + gl_FragCoord.xy / u_size * scale``.
  At the default view on a target of the content's aspect, offset = (0, 0) and scale = (1, 1)
  exactly, so the viewer and ``inshade render`` evaluate the very same uvs.
- ``orbit``: around a target (yaw, pitch, distance); ``fly``: free position + yaw/pitch.
  Both are right-handed, y up, looking down -z (the project convention), built with pyrr, and
  give ``u_view_matrix``, ``u_proj``, ``u_inv_view_proj`` (mat4, column-major bytes) and ``u_eye``.

Navigation methods take screen-space deltas in pixels (y down, as glfw reports the cursor), so the
app only forwards input; the math is here and unit-tested. ``from_dict(camera.to_dict())`` is an
identity, used for bookmarks, scene files and screenshot sidecars.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np
import pyrr


class CameraError(ValueError):
    """A camera description that cannot be used."""


def _mat_bytes(m) -> bytes:
    # pyrr matrices are laid out for row vectors (v @ M); their C-order bytes are column-major
    # for GLSL's M * v.
    return np.asarray(m, dtype="f4").tobytes()


@dataclass
class Plane2DCamera:
    kind = "plane2d"
    center: tuple = (0.5, 0.5)    # uv at the target's centre
    zoom: float = 1.0             # 1 = the unit square fits the target
    aspect: float = 1.0           # content width / height (the field's picture aspect)
    min_zoom: float = 0.05
    max_zoom: float = 512.0

    def scale(self, width: int, height: int) -> tuple[float, float]:
        """uv extent of the target, fitted so the whole unit square shows at zoom 1."""
        a = width / height
        if a >= self.aspect:
            ey = 1.0 / self.zoom
            ex = ey * a / self.aspect
        else:
            ex = 1.0 / self.zoom
            ey = ex * self.aspect / a
        return ex, ey

    def view(self, width: int, height: int) -> tuple[float, float, float, float]:
        ex, ey = self.scale(width, height)
        return (self.center[0] - 0.5 * ex, self.center[1] - 0.5 * ey, ex, ey)

    def uniforms(self, width: int, height: int) -> dict:
        return {"u_view": tuple(float(v) for v in self.view(width, height))}

    def uv_at(self, x: float, y: float, width: int, height: int) -> tuple[float, float]:
        """uv under window pixel (x, y), y down from the top edge."""
        ox, oy, sx, sy = self.view(width, height)
        return ox + x / width * sx, oy + (height - y) / height * sy

    def pan(self, dx: float, dy: float, width: int, height: int) -> None:
        """Drag by (dx, dy) pixels: the picture follows the cursor."""
        ex, ey = self.scale(width, height)
        self.center = (self.center[0] - dx / width * ex, self.center[1] + dy / height * ey)

    def zoom_at(self, factor: float, x: float, y: float, width: int, height: int) -> None:
        """Zoom by ``factor`` keeping the uv under pixel (x, y) fixed."""
        before = self.uv_at(x, y, width, height)
        self.zoom = float(np.clip(self.zoom * factor, self.min_zoom, self.max_zoom))
        after = self.uv_at(x, y, width, height)
        self.center = (self.center[0] + before[0] - after[0], self.center[1] + before[1] - after[1])

    def frame(self) -> None:
        self.center, self.zoom = (0.5, 0.5), 1.0

    def to_dict(self) -> dict:
        return {"type": self.kind, "center": [float(c) for c in self.center], "zoom": float(self.zoom),
                "aspect": float(self.aspect)}


@dataclass
class _Camera3D:
    fov_y: float = 45.0   # degrees
    near: float = 0.05
    far: float = 100.0

    def projection(self, width: int, height: int) -> np.ndarray:
        return pyrr.matrix44.create_perspective_projection(self.fov_y, width / height, self.near, self.far,
                                                           dtype=np.float64)

    def uniforms(self, width: int, height: int) -> dict:
        view = self.view_matrix()
        proj = self.projection(width, height)
        view_proj = view @ proj  # row-vector convention: v @ view @ proj
        return {"u_view_matrix": _mat_bytes(view), "u_proj": _mat_bytes(proj),
                "u_inv_view_proj": _mat_bytes(np.linalg.inv(view_proj)),
                "u_eye": tuple(float(v) for v in self.eye())}

    def forward(self) -> np.ndarray:
        return _direction(self.yaw, self.pitch)

    def to_dict(self) -> dict:
        out = {"type": self.kind}
        for f in fields(self):
            v = getattr(self, f.name)
            out[f.name] = [float(x) for x in v] if isinstance(v, (tuple, list, np.ndarray)) else float(v)
        return out


def _direction(yaw: float, pitch: float) -> np.ndarray:
    """Unit view direction; yaw = pitch = 0 looks down -z; yaw > 0 turns towards -x... see tests."""
    y, p = math.radians(yaw), math.radians(pitch)
    return np.array([-math.sin(y) * math.cos(p), math.sin(p), -math.cos(y) * math.cos(p)])


@dataclass
class OrbitCamera(_Camera3D):
    kind = "orbit"
    target: tuple = (0.0, 0.0, 0.0)
    distance: float = 3.0
    yaw: float = 0.0
    pitch: float = 0.0
    orbit_speed: float = 0.3   # degrees per pixel
    max_pitch: float = 89.0

    def eye(self) -> np.ndarray:
        return np.asarray(self.target, float) - self.distance * self.forward()

    def view_matrix(self) -> np.ndarray:
        return pyrr.matrix44.create_look_at(self.eye(), np.asarray(self.target, float), [0.0, 1.0, 0.0],
                                            dtype=np.float64)

    def orbit(self, dx: float, dy: float) -> None:
        self.yaw = (self.yaw + dx * self.orbit_speed) % 360.0
        self.pitch = float(np.clip(self.pitch - dy * self.orbit_speed, -self.max_pitch, self.max_pitch))

    def pan(self, dx: float, dy: float, width: int, height: int) -> None:
        """Move the target in the view plane so the point under the cursor follows it."""
        per_px = 2.0 * self.distance * math.tan(math.radians(self.fov_y) / 2) / height
        fwd = self.forward()
        right = np.cross(fwd, [0.0, 1.0, 0.0])
        right /= np.linalg.norm(right)
        up = np.cross(right, fwd)
        self.target = tuple(np.asarray(self.target, float) + per_px * (-dx * right + dy * up))

    def zoom(self, factor: float) -> None:
        self.distance = float(np.clip(self.distance * factor, 1e-4, 1e6))

    def frame(self, lo, hi) -> None:
        """Aim at the centre of box [lo, hi] from a distance at which its bounding sphere fits."""
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        radius = 0.5 * float(np.linalg.norm(hi - lo))
        self.target = tuple(0.5 * (lo + hi))
        self.distance = radius / math.sin(math.radians(self.fov_y) / 2)


@dataclass
class FlyCamera(_Camera3D):
    kind = "fly"
    position: tuple = (0.0, 0.0, 3.0)
    yaw: float = 0.0
    pitch: float = 0.0
    speed: float = 1.0          # units per second
    look_speed: float = 0.2     # degrees per pixel

    def eye(self) -> np.ndarray:
        return np.asarray(self.position, float)

    def view_matrix(self) -> np.ndarray:
        eye = self.eye()
        return pyrr.matrix44.create_look_at(eye, eye + self.forward(), [0.0, 1.0, 0.0], dtype=np.float64)

    def look(self, dx: float, dy: float) -> None:
        self.yaw = (self.yaw + dx * self.look_speed) % 360.0
        self.pitch = float(np.clip(self.pitch - dy * self.look_speed, -89.0, 89.0))

    def move(self, forward: float, right: float, up: float, dt: float) -> None:
        fwd = self.forward()
        r = np.cross(fwd, [0.0, 1.0, 0.0])
        r /= np.linalg.norm(r)
        step = self.speed * dt * (forward * fwd + right * r + up * np.array([0.0, 1.0, 0.0]))
        self.position = tuple(self.eye() + step)

    def frame(self, lo, hi) -> None:
        orbit = OrbitCamera(fov_y=self.fov_y, yaw=self.yaw, pitch=self.pitch)
        orbit.frame(lo, hi)
        self.position = tuple(orbit.eye())


CAMERAS = {c.kind: c for c in (Plane2DCamera, OrbitCamera, FlyCamera)}


def camera_from_dict(data: dict, where: str = "camera"):
    """Build a camera from its JSON form; CameraError names the field that is wrong."""
    if not isinstance(data, dict):
        raise CameraError(f"{where}: must be an object with a 'type'")
    kind = data.get("type")
    if kind not in CAMERAS:
        raise CameraError(f"{where}.type: unknown camera {kind!r} (known: {', '.join(CAMERAS)})")
    cls = CAMERAS[kind]
    names = {f.name: f for f in fields(cls)}
    kwargs = {}
    for key, value in data.items():
        if key == "type":
            continue
        if key not in names:
            raise CameraError(f"{where}.{key}: not a field of a {kind} camera (fields: {', '.join(names)})")
        default = names[key].default
        if isinstance(default, tuple):
            if not isinstance(value, (list, tuple)) or len(value) != len(default) or \
                    not all(_is_number(v) for v in value):
                raise CameraError(f"{where}.{key}: must be {len(default)} numbers, got {value!r}")
            value = tuple(float(v) for v in value)
        else:
            if not _is_number(value) or not math.isfinite(value):
                raise CameraError(f"{where}.{key}: must be a finite number, got {value!r}")
            value = float(value)
        kwargs[key] = value
    camera = cls(**kwargs)
    if kind == "plane2d" and (camera.zoom <= 0 or camera.aspect <= 0):
        raise CameraError(f"{where}: zoom and aspect must be > 0")
    return camera


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)
