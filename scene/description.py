"""Scenes are data: what to draw (program, networks), how to look at it (camera, bookmarks), what to
compare with (reference), the lights/environment, and the knobs a UI may turn (settings with ranges).

One small ``scene.json`` per asset, read by both ``inshade render`` and ``inshade view``:

    {"format": "inshade.scene", "version": 1, "name": "my_image",
     "program": "passes/field2d.frag", "size": [256, 256],
     "networks": [{"bundle": ".", "prefix": "net", "output": "rgb"}],
     "reference": {"image": "reference.png", "colour": "srgb", "space": "field"},
     "camera": {"type": "plane2d"}, "bookmarks": {"eye": {"type": "plane2d", "center": [0.4, 0.6], "zoom": 4}},
     "lights": [], "environment": null,
     "display": {"mode": "final", "modes": ["final", "network", "reference", "error", "split"], "split": 0.5},
     "settings": {"exposure": {"type": "float", "default": 1.0, "min": 0.0, "max": 8.0, "uniform": "u_exposure"},
                  "storage": {"type": "choice", "default": "auto", "choices": ["auto", "ubo"], "codegen": "storage"}}}

A setting is bound to exactly one of: ``uniform`` (set each frame, no recompile), ``define``
(a ``#define``, recompiles the program), ``codegen`` (an option of ``codegen.generate``, e.g.
weight storage or LUT filtering; regenerates and recompiles), ``environment`` (the SH lighting
computed on the CPU) or ``frame`` (read by the technique's per-frame hook, no recompile).
``"lights"`` lists at most 4 lights, point ``{"type": "point", "position": [x, y, z], "intensity": I}``
(inverse-square falloff) or directional ``{"type": "directional", "direction": [x, y, z], "intensity":
I}`` (the direction towards the light, normalised here; irradiance I), uploaded as ``u_lights`` +
``u_light_kinds`` to programs that include ``lib/lights`` (its ``scene_light`` handles both kinds; a
program that reads ``u_lights`` as positions only is refused a directional light at render time).

An analytic SDF scene (geometry/sdf.py) names its description file in ``"sdf": "sdf.json"``, may
have ``"networks": []``, and lights the scene with ``"environment": {"sky": preset, "rotation":
degrees, "degree": 4, "intensity": 1}`` (a procedural sky of inshade.sh, projected to SH, its
radiance scaled by the intensity); settings bound to ``"environment": "sky" | "rotation" |
"intensity"`` override those at run time. A network SDF (an MLP fitted
to a mesh, codegen/network_sdf.py) is ``"sdf": {"network": "sdf_bundle"}`` instead: the bundle is
compiled into the same ``sdf_scene`` chunk, so every SDF pass traces it unchanged.

The ``program`` names a fragment chunk that a registered technique draws (inshade/technique.py
``ProgramSpec``): the spec says what the program needs (geometry, mesh attributes, bundle kinds,
SH degree, uniforms, extra chunks, per-frame work) and the scene is checked against it here. A
mesh scene has ``"mesh": "mesh.ply"`` (OBJ/PLY/GLB, geometry/mesh.py) or a built-in shape,
``"mesh": {"shape": "teapot", "segments": 12}`` (``sphere``: radius, segments; ``plane``: size,
segments; geometry/shapes.py), instead of ``"sdf"``: the
renderer rasterises a G-buffer first (runtime/geometry.py MeshGBuffer), then the full-screen pass
shades each covered pixel once.
The environment of SDF and mesh scenes may also be an equirectangular map,
``"environment": {"map": "env.exr", "rotation": 0}`` (projected to SH at load time; a bad map is one
SceneError naming the file), selected by ``"sky": "map"``.

A choice setting bound to a uniform sets the index of its value in ``choices``, unless the program
declares that uniform's values (``ProgramSpec.choices``): then the setting may list only declared
values (any subset, any order) and sets the declared index; a define-bound or int setting of a
declared choice holds declared indices only.

A folder with only a bundle (no scene.json) is still a scene: it is derived from the bundle's
``render`` field (the format before scenes existed). Every problem is one ``SceneError`` naming the
file and the field.

Each part of the file is read by its own module: settings.py, geometry_ref.py (sdf, mesh),
networks.py (networks, a bundle's render field), lighting.py (lights, environment), views.py
(camera, bookmarks, display, reference), textures.py, assets.py (finding scenes by name), with
the error and the file names in common.py; this module holds the ``Scene`` and reads a whole file.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from inshade import technique
from inshade.json_header import check_header
from inshade.shaders import find_chunk

from .assets import ASSETS_ENV, asset_roots, list_scenes, resolve_asset
from .camera import CameraError, camera_from_dict
from .common import BUNDLE_FILE, MAX_SIZE, SCENE_FILE, SceneError, check_image
from .display import UI_MODES, DisplayMode
from .geometry_ref import MeshRef, NetworkSdfRef, check_geometry, parse_mesh, parse_sdf
from .labels import parse_labels
from .lighting import (LIGHT_KINDS, LIGHT_TYPES, MAX_LIGHTS, DirectionalLight, PointLight, check_sky_settings,
                       light_uniforms, parse_environment, parse_lights)
from .networks import NetworkRef, RenderSpecError, parse_networks, render_spec
from .settings import (BINDINGS, BUILTIN_SETTINGS, CODEGEN_OPTIONS, ENVIRONMENT_TARGETS, SETTING_TYPES, Setting,
                       bind_declared_choices, codegen_option_path, parse_settings)
from .textures import TEXTURE_KEYS, SceneTexture, parse_textures
from .views import REFERENCE_SPACES, Reference, check_camera, parse_bookmarks, parse_display, parse_reference

# What the rest of inshade imports from here, wherever it is defined.
__all__ = ["ASSETS_ENV", "BINDINGS", "BUILTIN_SETTINGS", "BUNDLE_FILE", "CODEGEN_OPTIONS", "ENVIRONMENT_TARGETS",
           "LIGHT_KINDS", "LIGHT_TYPES", "MAX_LIGHTS", "MAX_SIZE", "REFERENCE_SPACES", "SCENE_FILE", "SETTING_TYPES",
           "TEXTURE_KEYS", "CameraError", "DirectionalLight", "MeshRef", "NetworkRef", "NetworkSdfRef", "PointLight",
           "Reference", "RenderSpecError", "Scene", "SceneError", "SceneTexture", "Setting", "asset_roots",
           "codegen_option_path", "is_scene", "light_uniforms", "list_scenes", "load_scene", "parse_scene",
           "render_spec", "resolve_asset", "scene_from_bundle"]

# the fields of a scene.json
_KEYS = {"format", "version", "name", "title", "program", "size", "networks", "reference", "camera",
         "bookmarks", "lights", "environment", "display", "settings", "requires", "notes", "sdf",
         "mesh", "textures", "labels"}


# The Scene is defined here, beside what reads it, rather than with its parts: notebooks register
# its picture under this module's name (inshade/notebook.py).
@dataclass
class Scene:
    name: str
    root: Path | None         # folder relative paths resolve against (None: a bundle in memory)
    path: Path | None         # the scene.json, or None if derived from a bundle
    program: str
    size: tuple[int, int]
    networks: list[NetworkRef]
    camera: dict
    reference: Reference | None = None
    title: str = ""
    bookmarks: dict = field(default_factory=dict)
    lights: list = field(default_factory=list)     # Point/DirectionalLight: u_lights (lib/lights.glsl)
    environment: dict | None = None
    display_mode: DisplayMode = DisplayMode.FINAL
    display_modes: tuple = UI_MODES
    split: float = 0.5
    settings: dict = field(default_factory=dict)   # name -> Setting
    requires: dict = field(default_factory=dict)   # {"gl": 330, "extensions": [...]}
    sdf: object = None        # inshade.geometry.sdf.SdfScene (analytic), NetworkSdfRef (network SDF) or None
    textures: list = field(default_factory=list)   # SceneTexture: plain images the program samples
    environment_map: object = None  # radiance SH [K, 3] (float64) of environment.map, before rotation
    mesh: object = None       # MeshRef for triangle-mesh scenes ("mesh": "mesh.ply"), else None
    labels: tuple = ()        # scene/labels.py Label: overlay texts/lines (window and PNG only)

    @property
    def lit(self) -> bool:
        """3D geometry lit by the SH environment (an SDF or a mesh): u_sh, the SH chunk."""
        return self.sdf is not None or self.mesh is not None

    @property
    def spec(self) -> technique.ProgramSpec:
        """What the scene's program needs (its technique's ``ProgramSpec``)."""
        return technique.program_spec(self.program)[1]

    @property
    def source(self) -> Path:
        """What to pass to ``load_scene`` to get this scene again."""
        return self.path if self.path is not None else self.root

    def make_camera(self, name: str | None = None):
        data = self.camera if name is None else self.bookmarks[name]
        return camera_from_dict(data)

    def default_settings(self) -> dict:
        return {name: s.default for name, s in self.settings.items()}

    def check_settings(self, values: dict, where: str = "settings") -> dict:
        out = self.default_settings()
        for name, value in (values or {}).items():
            if name not in self.settings:
                raise SceneError(f"{where}: unknown setting {name!r} (this scene has: {', '.join(self.settings)})")
            out[name] = self.settings[name].check(value, where)
        return out


def is_scene(path) -> bool:
    """Whether ``load_scene`` reads ``path`` as a scene (not as a bare bundle): a folder with a
    scene.json, a scene .json file, or a file a technique opens (``Technique.opens``)."""
    path = Path(path)
    return ((path / SCENE_FILE).is_file() or (path.suffix == ".json" and path.name != BUNDLE_FILE)
            or (path.is_file() and technique.opener(path.suffix) is not None))


def load_scene(path) -> Scene:
    """A scene from a scene.json, a folder holding one, a bundle (folder or bundle.json), or a file
    a technique opens as a scene (``Technique.opens``: e.g. a .glb drawn by its reference pass)."""
    path = Path(path)
    if path.is_dir():
        if (path / SCENE_FILE).is_file():
            return _parse_file(path / SCENE_FILE)
        if (path / BUNDLE_FILE).is_file():
            return scene_from_bundle(path)
        raise SceneError(f"{path}: neither {SCENE_FILE} nor {BUNDLE_FILE} here")
    if not path.exists():
        raise SceneError(f"{path}: no such file or folder")
    if path.name == BUNDLE_FILE:
        return scene_from_bundle(path)
    make = technique.opener(path.suffix)
    if make is not None:   # a file a technique draws as a scene (Technique.opens), e.g. a glTF asset
        try:
            return parse_scene(make(path), root=path.parent, path=path)
        except (SceneError, CameraError) as exc:
            raise SceneError(str(exc) if str(exc).startswith(str(path)) else f"{path}: {exc}") from None
    return _parse_file(path)



def _parse_file(path: Path) -> Scene:
    from inshade.bundle import JSONFileError, read_json

    try:
        data = read_json(path)
    except JSONFileError as exc:
        raise SceneError(f"{path}: {exc}") from None
    try:
        return parse_scene(data, root=path.parent, path=path)
    except (SceneError, CameraError) as exc:
        raise SceneError(f"{path}: {exc}") from None


def parse_scene(data, *, root: Path, path: Path | None = None) -> Scene:
    """Check a scene's JSON object; errors name the field (the caller prefixes the file). The
    fields are checked in a fixed order, so a file with several faults is told the first one."""
    name, program, spec, size = _header(data)
    sdf = parse_sdf(data.get("sdf"), root)
    networks = data.get("networks")
    if spec.bundle_kinds and not networks:
        raise SceneError(f"networks: {program} needs a network of kind {' or '.join(map(repr, spec.bundle_kinds))}: "
                         "[{\"bundle\": \"folder\"}]")
    mesh = parse_mesh(data.get("mesh"), root)
    check_geometry(sdf, mesh, spec)
    refs = parse_networks(networks, root, spec, sdf)
    reference = parse_reference(data.get("reference"), root)
    camera = data.get("camera", {"type": "plane2d"})
    check_camera(camera, "camera")
    bookmarks = parse_bookmarks(data.get("bookmarks", {}))
    lights = parse_lights(data.get("lights", []))
    lit = sdf is not None or mesh is not None
    environment, environment_map = parse_environment(data.get("environment"), root, lit, spec)
    mode, modes, split = parse_display(data.get("display", {}))
    requires = data.get("requires", {})
    if not isinstance(requires, dict):
        raise SceneError("requires: must be an object, e.g. {\"gl\": 330, \"extensions\": []}")
    settings = parse_settings(data.get("settings", {}), "settings")
    bind_declared_choices(settings, spec)
    if lit:
        check_sky_settings(settings, environment_map is not None)
    textures = parse_textures(data.get("textures", []), root)
    try:
        labels = parse_labels(data.get("labels"), settings, [m.label for m in UI_MODES])
    except ValueError as exc:
        raise SceneError(str(exc)) from None
    title = data.get("title", name)
    scene = Scene(textures=textures, name=name, root=root, path=path, program=program, size=tuple(size), networks=refs,
                  camera=camera, reference=reference, title=str(title), bookmarks=bookmarks, lights=lights,
                  environment=environment, display_mode=mode, display_modes=modes, split=split,
                  settings=settings, requires=requires, sdf=sdf, environment_map=environment_map,
                  mesh=mesh, labels=labels)
    if spec.validate is not None:   # what only the program's technique can check
        try:
            spec.validate(scene)
        except ValueError as exc:
            raise SceneError(str(exc)) from None
    return scene


def _header(data) -> tuple[str, str, technique.ProgramSpec, list]:
    """(name, program, its spec, size): what a scene.json says it is and draws."""
    check_header(data, "inshade.scene", _KEYS, SceneError)
    name = data.get("name")
    if not isinstance(name, str) or not name:
        raise SceneError("name: must be a non-empty string")
    program = data.get("program")
    if not isinstance(program, str):
        raise SceneError(f"program: must name a fragment chunk, e.g. \"passes/field2d.frag\", got {program!r}")
    try:
        spec = technique.program_spec(program)[1]
    except technique.TechniqueError as exc:
        raise SceneError(f"program: {exc}") from None
    if find_chunk(program) is None:
        raise SceneError(f"program: no shader chunk {program!r} on the search path")
    size = data.get("size", [256, 256])
    if not (isinstance(size, list) and len(size) == 2 and all(
            isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= MAX_SIZE for v in size)):
        raise SceneError(f"size: must be [width, height], ints in 1..{MAX_SIZE}, got {size!r}")
    return name, program, spec, size


def scene_from_bundle(bundle) -> Scene:
    """The scene a bundle's ``render`` field describes (bundles made before scene.json existed)."""
    from inshade.bundle import Bundle, load

    if not isinstance(bundle, Bundle):
        bundle = load(bundle)
    spec = render_spec(bundle)   # RenderSpecError if there is no usable render field
    reference, root = None, None
    if bundle.path is not None:
        root = Path(bundle.path).parent if Path(bundle.path).is_file() else Path(bundle.path)
        if (root / "reference.png").is_file():  # what `inshade train` writes beside the bundle
            check_image(root / "reference.png", "reference", exr=False)
            reference = Reference(root / "reference.png")
    return Scene(name=bundle.name, root=root, path=None, program=spec["program"],
                 size=(spec["width"], spec["height"]),
                 networks=[NetworkRef(Path(bundle.path) if bundle.path is not None else None, "net", spec["output"])],
                 camera={"type": "plane2d", "aspect": spec["width"] / spec["height"]},
                 reference=reference, title=bundle.name,
                 settings=parse_settings({}, "render"))
