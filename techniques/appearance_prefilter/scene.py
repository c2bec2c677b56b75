"""Procedural test scenes for appearance prefiltering, normalised into the unit box [0, 1]^3.

- ``grove``: instanced trees (a closed cylinder trunk, a crown of many thin two-sided leaf cards
  in varied greens), a field of small glossy objects (closed icospheres and boxes, roughness
  0.2-0.5, some metallic) and the hidden-occlusion case, ``slabs``.
- ``forest``: the paper's size class (ship: > 1 M triangles): a few detailed tree prototypes
  (closed trunks and branches with displaced bark, crowns of tens of thousands of two-sided leaf
  cards) instanced, turned and scaled over a jittered grid.
- ``slabs``: a block of aligned thin parallel slabs (closed thin boxes). Seen along the slab
  planes the gaps line up at every depth (coverage strongly correlated across depth), which a
  statistical aggregate (SGGX/EGGX-style, exponential transmittance) gets wrong; seen across
  them the block is opaque.

``build_scene(name, detail)`` is deterministic (seeded per scene). ``scene_from_mesh`` puts a
user mesh through the same checks: non-empty, finite vertices, and every solid (not two-sided)
part watertight -- the bake's shading assumes closed solids are seen from outside.

numpy + trimesh; no torch.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import trimesh

DETAILS = ("ship", "quick")
# geometry stays off the unit box faces (no voxel index past the grid); neither this nor the
# slabs' extent is a dyadic fraction, so no bounding face lies on a cell boundary of any scale
MARGIN = 0.0123


class SceneError(ValueError):
    """Unusable scene input; the message names the field."""


@dataclass
class Part:
    """One named piece before assembly: a mesh and its (uniform or per-face) material."""

    name: str
    mesh: trimesh.Trimesh
    base_colour: np.ndarray       # [3] or [F, 3] linear RGB
    roughness: float | np.ndarray
    metallic: float | np.ndarray
    two_sided: bool


@dataclass
class PrefilterScene:
    """A mesh in [0, 1]^3 (y up) with per-face materials; ``parts`` = [(name, face start, face stop)]."""

    name: str
    mesh: trimesh.Trimesh
    base_colour: np.ndarray   # [F, 3] float32 linear
    roughness: np.ndarray     # [F] float32
    metallic: np.ndarray      # [F] float32
    two_sided: np.ndarray     # [F] bool
    parts: list = field(default_factory=list)

    @property
    def faces(self) -> int:
        return len(self.mesh.faces)


# --- checks -------------------------------------------------------------------------------------

def _per_face(value, n: int, width: int | None, name: str, what: str) -> np.ndarray:
    a = np.asarray(value, np.float64)
    shape = (n,) if width is None else (n, width)
    try:
        a = np.broadcast_to(a, shape)
    except ValueError:
        raise SceneError(f"{what}.{name}: expected one value or one per face {shape}, got shape {a.shape}") from None
    if not np.all(np.isfinite(a)) or a.min() < 0.0 or (name != "base_colour" and a.max() > 1.0):
        raise SceneError(f"{what}.{name}: values must be finite and in [0, 1]")
    return np.ascontiguousarray(a, np.float32)


def _check_mesh(mesh, what: str) -> None:
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0 or len(mesh.vertices) == 0:
        raise SceneError(f"{what}.mesh: empty geometry (no faces)")
    if not np.all(np.isfinite(mesh.vertices)):
        raise SceneError(f"{what}.mesh: vertices contain NaN or inf")


def scene_from_mesh(mesh, base_colour, roughness, metallic, two_sided, name: str = "mesh",
                    parts=None, normalise: bool = True, extent: float = 1.0 - 2.0 * MARGIN) -> PrefilterScene:
    """A user mesh (any units) as a PrefilterScene, checked and (by default) normalised into the
    unit box: the largest extent maps to ``extent`` (<= 1 - 2 MARGIN), centred at 0.5. ``parts`` [(name, start, stop)]
    defaults to one part; a part whose faces are not all two-sided must be watertight."""
    _check_mesh(mesh, name)
    n = len(mesh.faces)
    base = _per_face(base_colour, n, 3, "base_colour", name)
    rough = _per_face(roughness, n, None, "roughness", name)
    metal = _per_face(metallic, n, None, "metallic", name)
    sided = np.ascontiguousarray(np.broadcast_to(np.asarray(two_sided, bool), (n,)))
    parts = list(parts) if parts is not None else [(name, 0, n)]
    for pname, start, stop in parts:
        if not (0 <= start < stop <= n):
            raise SceneError(f"{name}.parts.{pname}: face range [{start}, {stop}) outside [0, {n})")
        if not sided[start:stop].all():
            piece = trimesh.Trimesh(mesh.vertices, mesh.faces[start:stop], process=False)
            piece.merge_vertices()
            if not piece.is_watertight:
                raise SceneError(f"{name}.parts.{pname}: a solid (not two_sided) part must be watertight; "
                                 "close it or mark it two_sided")
    vertices = np.asarray(mesh.vertices, np.float64)
    if normalise:
        lo, hi = vertices.min(0), vertices.max(0)
        size, target = float((hi - lo).max()), float(extent)
        if size <= 0.0:
            raise SceneError(f"{name}.mesh: all vertices coincide (zero extent)")
        if not 0.0 < target <= 1.0 - 2.0 * MARGIN:
            raise SceneError(f"{name}.extent: must be in (0, {1.0 - 2.0 * MARGIN}], got {target!r}")
        vertices = (vertices - 0.5 * (lo + hi)) * (target / size) + 0.5
    elif vertices.min() < 0.0 or vertices.max() > 1.0:
        raise SceneError(f"{name}.mesh: vertices outside the unit box (pass normalise=True)")
    out = trimesh.Trimesh(vertices, np.asarray(mesh.faces), process=False)
    return PrefilterScene(name, out, base, rough, metal, sided, parts)


def assemble(name: str, parts: list[Part], extent: float = 1.0 - 2.0 * MARGIN) -> PrefilterScene:
    """Concatenate parts (each checked on its own) into one normalised scene (largest extent ``extent``)."""
    meshes, base, rough, metal, sided, ranges = [], [], [], [], [], []
    start = 0
    for part in parts:
        _check_mesh(part.mesh, f"{name}.parts.{part.name}")
        n = len(part.mesh.faces)
        meshes.append(part.mesh)
        base.append(_per_face(part.base_colour, n, 3, "base_colour", f"{name}.parts.{part.name}"))
        rough.append(_per_face(part.roughness, n, None, "roughness", f"{name}.parts.{part.name}"))
        metal.append(_per_face(part.metallic, n, None, "metallic", f"{name}.parts.{part.name}"))
        sided.append(np.full(n, part.two_sided))
        ranges.append((part.name, start, start + n))
        start += n
    if not meshes:
        raise SceneError(f"{name}.parts: empty geometry (no parts)")
    mesh = trimesh.util.concatenate(meshes)
    return scene_from_mesh(mesh, np.concatenate(base), np.concatenate(rough), np.concatenate(metal),
                           np.concatenate(sided), name=name, parts=ranges, extent=extent)


# --- building blocks ----------------------------------------------------------------------------

def _rotation(rng) -> np.ndarray:
    return trimesh.transformations.random_rotation_matrix(rng.random(3))


def _leaf_cards(rng, centre, radii, count: int, size: float) -> trimesh.Trimesh:
    """``count`` two-triangle cards of edge ~``size`` scattered in an ellipsoid, random orientations."""
    d = rng.normal(size=(count, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    pos = np.asarray(centre) + d * rng.random((count, 1)) ** (1.0 / 3.0) * np.asarray(radii)
    # card spanned by two random orthogonal axes
    a = rng.normal(size=(count, 3))
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b = np.cross(a, rng.normal(size=(count, 3)))
    b /= np.linalg.norm(b, axis=1, keepdims=True)
    s = size * (0.7 + 0.6 * rng.random((count, 1)))
    corners = np.stack([pos - a * s * 0.5 - b * s * 0.25, pos + a * s * 0.5 - b * s * 0.25,
                        pos + a * s * 0.5 + b * s * 0.25, pos - a * s * 0.5 + b * s * 0.25], 1)
    verts = corners.reshape(-1, 3)
    base = 4 * np.arange(count)[:, None]
    faces = np.concatenate([base + [0, 1, 2], base + [0, 2, 3]], 0)
    return trimesh.Trimesh(verts, faces, process=False)


def _tree_parts(rng, origin, height: float, leaves: int, tag: str) -> list[Part]:
    trunk_h = 0.45 * height
    trunk = trimesh.creation.cylinder(radius=0.04 * height, height=trunk_h, sections=12)
    trunk.apply_transform(trimesh.transformations.rotation_matrix(-math.pi / 2, [1, 0, 0]))  # axis z -> y
    trunk.apply_translation(np.asarray(origin) + [0.0, trunk_h / 2, 0.0])
    crown_c = np.asarray(origin) + [0.0, trunk_h + 0.3 * height, 0.0]
    cards = _leaf_cards(rng, crown_c, [0.3 * height, 0.33 * height, 0.3 * height], leaves, 0.09 * height)
    greens = np.array([0.05, 0.22, 0.04]) * (0.6 + 0.8 * rng.random((leaves, 1))) + \
        np.array([0.04, 0.03, 0.0]) * rng.random((leaves, 1))
    return [Part(f"{tag}_trunk", trunk, [0.18, 0.11, 0.06], 0.8, 0.0, False),
            Part(f"{tag}_leaves", cards, np.repeat(np.clip(greens, 0, 1), 2, axis=0), 0.55, 0.0, True)]


def _glossy_field(rng, count: int, lo, hi, subdivisions: int) -> list[Part]:
    parts = []
    for i in range(count):
        size = 0.05 + 0.05 * rng.random()
        if rng.random() < 0.6:
            m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=size)
        else:
            m = trimesh.creation.box(extents=size * (1.0 + rng.random(3)))
            m.apply_transform(_rotation(rng))
        pos = np.asarray(lo) + rng.random(3) * (np.asarray(hi) - np.asarray(lo))
        m.apply_translation(pos + [0.0, size, 0.0])
        colour = 0.05 + 0.85 * rng.random(3)
        metallic = 1.0 if rng.random() < 0.3 else 0.0
        parts.append(Part(f"glossy_{i:03d}", m, colour, 0.2 + 0.3 * rng.random(), metallic, False))
    return parts


def _slab_block(origin, count: int, thickness: float, gap: float, depth: float, height: float) -> list[Part]:
    """``count`` closed thin boxes, parallel to the y-z plane (normal x), stepped along x."""
    parts = []
    for i in range(count):
        m = trimesh.creation.box(extents=[thickness, height, depth])
        m.apply_translation(np.asarray(origin) + [i * (thickness + gap), height / 2, depth / 2])
        parts.append(Part(f"slab_{i:02d}", m, [0.7, 0.62, 0.5], 0.45, 0.0, False))
    return parts


def _bark(rng, radius: float, height: float, sections: int, rings: int, taper: float = 0.35) -> trimesh.Trimesh:
    """A closed trunk along +y from the origin: a tapered cylinder grid (``sections`` around,
    ``rings`` up) displaced radially by bark furrows (vertical ridges that wander with height, plus
    a finer cross-grain), capped by a fan at each end: watertight."""
    theta = 2.0 * math.pi * np.arange(sections) / sections
    y = np.linspace(0.0, 1.0, rings + 1)
    phase = rng.uniform(0.0, 2.0 * math.pi, 3)
    t, v = np.meshgrid(theta, y)                                           # [rings + 1, sections]
    furrows = np.abs(np.sin(0.5 * (sections // 4) * t + 2.5 * np.sin(7.0 * v + phase[0])))
    grain = np.sin(60.0 * v + 3.0 * t + phase[1]) * np.sin(23.0 * t + phase[2])
    r = radius * (1.0 - taper * v) * (0.9 + 0.12 * furrows + 0.025 * grain)
    ring_pts = np.stack([r * np.cos(t), v * height, r * np.sin(t)], -1).reshape(-1, 3)
    verts = np.concatenate([ring_pts, [[0.0, 0.0, 0.0], [0.0, height, 0.0]]])
    i = np.arange(rings)[:, None] * sections
    j = np.arange(sections)[None, :]
    a, b = i + j, i + (j + 1) % sections
    c, d = a + sections, b + sections
    side = np.concatenate([np.stack([a, c, b], -1).reshape(-1, 3), np.stack([b, c, d], -1).reshape(-1, 3)])
    bottom, top = len(ring_pts), len(ring_pts) + 1
    last = rings * sections
    caps = np.concatenate([np.stack([np.full(sections, bottom), (j[0] + 1) % sections, j[0]], -1),
                           np.stack([np.full(sections, top), last + j[0], last + (j[0] + 1) % sections], -1)])
    mesh = trimesh.Trimesh(verts, np.concatenate([side, caps]), process=False)
    if mesh.volume < 0:   # outward winding
        mesh.invert()
    return mesh


def _placed(mesh: trimesh.Trimesh, origin, yaw: float, scale: float, tilt=None) -> trimesh.Trimesh:
    m = mesh.copy()
    if tilt is not None:
        m.apply_transform(tilt)
    m.apply_scale(scale)
    m.apply_transform(trimesh.transformations.rotation_matrix(yaw, [0, 1, 0]))
    m.apply_translation(origin)
    return m


def _forest_tree(rng, detail: dict) -> list[tuple]:
    """One tree prototype at the origin, height 1: (name, mesh, colour, roughness, two_sided) pieces:
    a displaced bark trunk, branches (thinner bark, tilted out of the crown's base) and a crown of
    leaf cards gathered around the branch tips."""
    sec, rings = detail["bark"]
    trunk = _bark(rng, 0.045, 0.62, sec, rings)
    pieces = [("trunk", trunk, [0.16, 0.1, 0.06], 0.85, False)]
    tips = []
    for k in range(detail["branches"]):
        yaw = 2.0 * math.pi * (k + rng.random() * 0.5) / detail["branches"]
        lift = 0.34 + 0.24 * rng.random()
        length = 0.22 + 0.1 * rng.random()
        tilt = trimesh.transformations.rotation_matrix(0.75 + 0.35 * rng.random(), [0, 0, -1])
        bark = _bark(rng, 0.016, length, max(sec // 3, 6), max(rings // 4, 4))
        branch = _placed(bark, [0.0, lift, 0.0], yaw, 1.0, tilt)
        pieces.append((f"branch{k}", branch, [0.17, 0.11, 0.07], 0.85, False))
        direction = tilt[:3, :3] @ [0.0, 1.0, 0.0]
        tip = trimesh.transformations.rotation_matrix(yaw, [0, 1, 0])[:3, :3] @ (direction * length)
        tips.append(np.array([0.0, lift, 0.0]) + tip)
    tips.append(np.array([0.0, 0.7, 0.0]))
    per = detail["cards"] // len(tips)
    cards, colours = [], []
    for tip in tips:
        cards.append(_leaf_cards(rng, tip, [0.17, 0.13, 0.17], per, 0.045))
        greens = np.array([0.06, 0.2, 0.035]) * (0.6 + 0.8 * rng.random((per, 1))) + \
            np.array([0.05, 0.035, 0.0]) * rng.random((per, 1))
        colours.append(np.tile(np.clip(greens, 0, 1), (2, 1)))   # a card's two triangles: i and per + i
    pieces.append(("leaves", trimesh.util.concatenate(cards), np.concatenate(colours), 0.5, True))
    return pieces


# --- the scenes ---------------------------------------------------------------------------------

def _grove(detail: str) -> list[Part]:
    rng = np.random.default_rng(14)
    ship = detail == "ship"
    # crowns are the voxel-hungry part (a volume of cards): sized so ship scales 3..7 stay ~40k voxels
    trees = [((-1.2, 0.0, -1.0), 0.95), ((0.3, 0.0, -1.4), 1.15), ((1.4, 0.0, -0.9), 0.85),
             ((-0.6, 0.0, 0.0), 0.8), ((1.3, 0.0, 1.2), 0.9)][: 5 if ship else 2]
    parts = []
    for i, (origin, height) in enumerate(trees):
        parts += _tree_parts(rng, origin, height, 1400 if ship else 200, f"tree{i}")
    parts += _glossy_field(rng, 70 if ship else 10, (-1.8, 0.0, 0.6), (0.2, 0.0, 1.8), 2 if ship else 1)
    parts += _slab_block((0.8, 0.0, -0.2 if ship else 0.2), 8 if ship else 5, 0.02, 0.06, 0.7, 0.7)
    return parts


# the forest's sizes per detail: bark grid (sections, rings), branches and leaf cards per tree
# prototype, how many prototypes and how many trees they are instanced into
FOREST = {"ship": dict(bark=(64, 160), branches=5, cards=36000, prototypes=3, trees=13),
          "quick": dict(bark=(8, 6), branches=2, cards=240, prototypes=2, trees=3)}


def _forest(detail: str) -> list[Part]:
    """Instanced detailed trees (ship: > 1 M triangles): a few prototypes (_forest_tree), each tree
    a prototype turned, scaled and placed on a jittered grid."""
    rng = np.random.default_rng(41)
    d = FOREST[detail]
    protos = [_forest_tree(rng, d) for _ in range(d["prototypes"])]
    side = math.ceil(math.sqrt(d["trees"]))
    parts = []
    for n in range(d["trees"]):
        gx, gz = n % side, n // side
        origin = [1.1 * (gx + 0.5 * (gz % 2) + 0.35 * (rng.random() - 0.5)), 0.0,
                  0.95 * (gz + 0.35 * (rng.random() - 0.5))]
        yaw, scale = 2.0 * math.pi * rng.random(), 0.8 + 0.45 * rng.random()
        for name, mesh, colour, rough, two_sided in protos[n % len(protos)]:
            parts.append(Part(f"tree{n:02d}_{name}", _placed(mesh, origin, yaw, scale), colour, rough, 0.0, two_sided))
    return parts


def _slabs(detail: str) -> list[Part]:
    return _slab_block((0.0, 0.0, 0.0), 8 if detail == "ship" else 5, 0.02, 0.06, 0.6, 0.6)


# (parts builder, largest extent in the unit box): the slab block alone takes the central half, so
# its big flat faces do not fill every cell of the finer scales (and a camera sees it whole)
SCENES = {"grove": (_grove, 1.0 - 2.0 * MARGIN), "slabs": (_slabs, 0.47), "forest": (_forest, 1.0 - 2.0 * MARGIN)}


def build_scene(name: str, detail: str = "ship") -> PrefilterScene:
    """The named scene at ``detail`` ("ship": grove ~20k-60k faces, forest > 1 M; "quick": < 3k), in [0, 1]^3."""
    if name not in SCENES:
        raise SceneError(f"scene: unknown {name!r} (known: {', '.join(SCENES)})")
    if detail not in DETAILS:
        raise SceneError(f"detail: must be one of {', '.join(DETAILS)}, got {detail!r}")
    build, extent = SCENES[name]
    return assemble(name, build(detail), extent)
