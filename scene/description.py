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
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

from inshade import technique
from inshade.codegen import FILTERS, OPTIONS, SHORTHANDS, STORAGE_MODES
from inshade.geometry.mesh import mesh_uv
from inshade.shaders import find_chunk

from .camera import CameraError, camera_from_dict
from .display import UI_MODES, DisplayMode, parse_mode
from .labels import parse_labels
from .tonemap import TONEMAPS

SCENE_FILE = "scene.json"
BUNDLE_FILE = "bundle.json"
MAX_SIZE = 16384
REFERENCE_SPACES = ("field", "screen")
SETTING_TYPES = ("float", "int", "bool", "choice")
# "frame": read only by the program's per-frame hook (ProgramSpec.frame), which turns it into uniforms.
# "present": a uniform of the present pass (the window, the page) that PNGs follow too, never seen by the
# float image (the tone mapper).
BINDINGS = ("uniform", "define", "codegen", "environment", "frame", "present")
# "environment" settings drive the lighting the renderer computes on the CPU (SDF scenes: the
# radiance SH uniform u_sh); a change re-uploads a uniform, no recompile.
ENVIRONMENT_TARGETS = ("sky", "rotation", "intensity")
# Codegen options a setting may drive: "<component type>.<option>" (codegen.OPTIONS) or a shorthand
# ("storage", "lut_filter", codegen.SHORTHANDS) -> its choices.
CODEGEN_OPTIONS = {**{f"{t}.{name}": choices for t, opts in OPTIONS.items() for name, (choices, _) in opts.items()},
                   **{short: OPTIONS[t][name][0] for short, (t, name) in SHORTHANDS.items()}}


def codegen_option_path(target: str) -> tuple[str, str]:
    """(component type, option) a setting's ``codegen`` target names."""
    return SHORTHANDS[target] if target in SHORTHANDS else tuple(target.split(".", 1))
# Codegen options every scene has, even when its file does not expose them in the UI.
BUILTIN_SETTINGS = {
    "storage": {"type": "choice", "default": "auto", "choices": list(STORAGE_MODES), "codegen": "storage",
                "label": "weight storage"},
    "lut_filter": {"type": "choice", "default": "exact", "choices": list(FILTERS), "codegen": "lut_filter",
                   "label": "LUT filtering"},
    # scene labels (scene/labels.py): drawn over the window and the PNG, never in the float image
    "labels": {"type": "bool", "default": True, "frame": "labels", "label": "labels"},
    # the tone mapper of the window, the page and PNGs (scene/tonemap.py); the float image and EXRs stay linear
    "tonemap": {"type": "choice", "default": "none", "choices": list(TONEMAPS), "present": "u_tonemap",
                "label": "tone mapping"},
}


class SceneError(ValueError):
    """A scene description that cannot be used; the message names the file and the field."""


@dataclass
class Setting:
    name: str
    type: str
    default: object
    binding: str              # "uniform" | "define" | "codegen"
    target: str               # uniform name, define name, or generate() keyword
    min: float | None = None
    max: float | None = None
    choices: tuple = ()
    label: str = ""
    exposed: bool = True      # shown in the UI (built-in codegen options are hidden unless declared)
    declared: technique.Choice | None = None   # the program's choice this setting drives (ProgramSpec.choices)

    def index(self, value) -> int:
        """The int a choice value sets on the program: the declared index of a value the program
        declares (an int value of a declared choice is that index already), else its place in
        ``choices``."""
        if self.declared is None:
            return self.choices.index(value)
        return value if isinstance(value, int) else self.declared.index(value)

    def check(self, value, where: str = "setting"):
        """Validate and normalise a value for this setting (SceneError if it does not fit)."""
        w = f"{where} {self.name!r}"
        if self.type == "choice":
            if value not in self.choices:
                raise SceneError(f"{w}: {value!r} is not one of {list(self.choices)}")
            return value
        if self.type == "bool":
            if not isinstance(value, bool) and type(value) is int and value in (0, 1):
                value = bool(value)      # --set labels=0 (the command line parses JSON)
            if not isinstance(value, bool):
                raise SceneError(f"{w}: must be true or false, got {value!r}")
            return value
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise SceneError(f"{w}: must be a finite number, got {value!r}")
        if self.type == "int":
            if int(value) != value:
                raise SceneError(f"{w}: must be an integer, got {value!r}")
            value = int(value)
        else:
            value = float(value)
        if (self.min is not None and value < self.min) or (self.max is not None and value > self.max):
            raise SceneError(f"{w}: {value} is outside [{self.min}, {self.max}]")
        return value


@dataclass
class NetworkRef:
    bundle: Path              # bundle folder (or bundle.json)
    prefix: str = "net"       # GLSL symbol prefix; the chunk is <network> for "net", <network_P> otherwise
    output: str | None = None  # the output port the program shows (None: the first)

    @property
    def chunk(self) -> str:
        return "network" if self.prefix == "net" else f"network_{self.prefix}"


@dataclass
class NetworkSdfRef:
    """``"sdf": {"network": "sdf_bundle"}``: a network SDF bundle traced as the scene's geometry
    (codegen/network_sdf.py); ``prefix`` names its GLSL function (``<prefix>_eval``)."""
    bundle: Path
    prefix: str = "sdfnet"

    @property
    def path(self) -> Path:
        return self.bundle

    @property
    def name(self) -> str:
        return self.bundle.name


@dataclass
class MeshRef:
    """``"mesh": "mesh.ply"``: a triangle mesh (geometry/mesh.py load_mesh), or ``"mesh": {"shape":
    "teapot", ...}``: a built-in one (geometry/shapes.py; ``path`` None), rasterised into a G-buffer
    (runtime/geometry.py MeshGBuffer) that a deferred pass (mesh_prt) shades."""
    path: Path | None
    data: object = None       # the trimesh.Trimesh
    shape: str | None = None  # built-in shape name
    params: dict = field(default_factory=dict)   # its parameters, defaults filled in
    gltf: object = None       # geometry.gltf.GltfAsset of a glTF mesh (its materials), else None

    @property
    def name(self) -> str:
        return self.path.name if self.path is not None else self.shape


@dataclass(frozen=True)
class PointLight:
    position: tuple[float, float, float]
    intensity: float
    kind = "point"

    def to_dict(self) -> dict:
        return {"type": "point", "position": list(self.position), "intensity": self.intensity}


@dataclass(frozen=True)
class DirectionalLight:
    direction: tuple[float, float, float]   # unit vector towards the light
    intensity: float                        # irradiance, no falloff
    kind = "directional"

    def to_dict(self) -> dict:
        return {"type": "directional", "direction": list(self.direction), "intensity": self.intensity}


@dataclass
class Reference:
    image: Path
    colour: str = "srgb"      # "srgb" (8-bit PNG, decoded to linear) or "linear" (EXR)
    space: str = "field"      # "field": lives in the camera's uv plane; "screen": a render of the same view


@dataclass
class SceneTexture:
    """An 8-bit image bound to a sampler uniform as stored (no colour decode: the program decides),
    image row 0 at v = 1 (uv (0,0) bottom-left), optionally with a GL-built mip chain."""
    uniform: str
    image: Path
    mipmaps: bool = True
    anisotropy: float = 1.0
    repeat: bool = True


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


class RenderSpecError(ValueError):
    """A bundle cannot be rendered headless: no or malformed `render` field."""


def render_spec(bundle: Bundle) -> dict:
    """The bundle's ``render`` field, checked against the bundle's ports; adds the output's
    lane offset and width as ``out_offset``/``out_dim``."""
    where = _where(bundle)
    spec = bundle.meta.get("render")
    if spec is None:
        raise RenderSpecError(f"bundle '{bundle.name}' ({where}) does not say what it is, so it cannot be drawn: "
                              "convert it again with --as image|sdf|field (inshade.export(..., as_=...); an image "
                              "also takes --colour srgb|linear)")
    if not isinstance(spec, dict):
        raise RenderSpecError(f"{where}: render: must be an object")
    program = spec.get("program")
    programs = {p.program: p for t in technique.techniques() for p in t.programs if p.field_inputs is not None}
    drawn_by = [p for t in technique.techniques() for p in t.programs if bundle.kind in p.bundle_kinds]
    if program is None and drawn_by:   # e.g. a PRT transfer network: its shading needs geometry
        raise RenderSpecError(f"{where}: a {bundle.kind} bundle is drawn by a scene, not on its own: a scene.json "
                              f"with \"program\": \"{drawn_by[0].program}\", its geometry "
                              f"(\"{drawn_by[0].geometry}\") and \"networks\": [{{\"bundle\": ...}}] naming this bundle")
    if program not in programs:
        raise RenderSpecError(f"{where}: render.program: unknown program {program!r} "
                              f"(known: {', '.join(programs)})")
    out = dict(spec)
    for key in ("width", "height"):
        v = spec.get(key, 256)
        if isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= MAX_SIZE:
            raise RenderSpecError(f"{where}: render.{key}: must be an int in 1..{MAX_SIZE}, got {v!r}")
        out[key] = v
    need = programs[program].field_inputs
    in_name = spec.get("input", bundle.inputs[0].name)
    if len(bundle.inputs) != 1 or bundle.inputs[0].name != in_name or bundle.inputs[0].dim != need:
        have = ", ".join(f"{p.name}[{p.dim}]" for p in bundle.inputs)
        raise RenderSpecError(f"{where}: render.input: {program} needs the bundle's only input to be "
                              f"{in_name!r} of width {need}; the bundle has {have}")
    out_name = spec.get("output", bundle.outputs[0].name)
    lanes = bundle.output_lanes(out_name)
    if lanes is None:
        raise RenderSpecError(f"{where}: render.output: no output named {out_name!r} "
                              f"(outputs: {', '.join(p.name for p in bundle.outputs)})")
    offset, dim = lanes
    if dim not in (1, 3, 4):
        raise RenderSpecError(f"{where}: render.output: {out_name!r} is {dim} wide; 1, 3 or 4 can be shown")
    out.update(program=program, input=in_name, output=out_name, out_offset=offset, out_dim=dim)
    return out


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
            _check_image(root / "reference.png", "reference", exr=False)
            reference = Reference(root / "reference.png")
    return Scene(name=bundle.name, root=root, path=None, program=spec["program"],
                 size=(spec["width"], spec["height"]),
                 networks=[NetworkRef(Path(bundle.path) if bundle.path is not None else None, "net", spec["output"])],
                 camera={"type": "plane2d", "aspect": spec["width"] / spec["height"]},
                 reference=reference, title=bundle.name,
                 settings=_settings({}, "render"))


def list_scenes(root) -> list[Path]:
    """Sub-folders of ``root`` (e.g. ``trained/``) that hold a scene.json or a bundle, sorted."""
    root = Path(root)
    if not root.is_dir():
        return []
    return sorted(p for p in root.iterdir() if p.is_dir() and ((p / SCENE_FILE).is_file() or (p / BUNDLE_FILE).is_file()))


ASSETS_ENV = "INSHADE_ASSETS"   # extra folders of assets, os.pathsep-separated, searched before trained/


def asset_roots() -> list[Path]:
    """Folders a bare asset name is looked up in: each folder of $INSHADE_ASSETS, then the shipped
    ``trained/`` (beside the package, in this editable layout)."""
    import os

    import inshade

    roots = [Path(p).expanduser() for p in os.environ.get(ASSETS_ENV, "").split(os.pathsep) if p]
    roots.append(Path(inshade.__file__).resolve().parents[1] / "trained")
    return roots


def resolve_asset(name_or_path) -> Path:
    """The path of an asset given as a path (used as is when it exists) or as a bare name such as
    ``prt_creature`` (looked up in ``asset_roots()``). A path that does not exist is a SceneError
    saying so, with the closest asset names."""
    import difflib

    path = Path(name_or_path)
    if path.exists():
        return path
    text = str(name_or_path)
    bare = bool(text) and path.name == text and text not in (".", "..")
    if bare:
        for root in asset_roots():
            if (root / text).exists():
                return root / text
    names = sorted({p.name for root in asset_roots() for p in list_scenes(root)})
    close = difflib.get_close_matches(path.name, names, n=3, cutoff=0.6)
    hint = f" (did you mean {', '.join(close)}?)" if close else \
        (f" (no such path, nor an asset in {', '.join(str(r) for r in asset_roots())})" if bare else "")
    raise SceneError(f"{text}: does not exist{hint}")


# parsing ---------------------------------------------------------------------------------------------
_KEYS = {"format", "version", "name", "title", "program", "size", "networks", "reference", "camera",
         "bookmarks", "lights", "environment", "display", "settings", "requires", "notes", "sdf",
         "mesh", "textures", "labels"}
TEXTURE_KEYS = {"uniform", "image", "mipmaps", "anisotropy", "repeat"}


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
    """Check a scene's JSON object; errors name the field (the caller prefixes the file)."""
    if not isinstance(data, dict):
        raise SceneError("must be a JSON object")
    if data.get("format") != "inshade.scene":
        raise SceneError(f"format: expected \"inshade.scene\", got {data.get('format')!r}")
    if data.get("version") != 1:
        raise SceneError(f"version: this inshade reads version 1, got {data.get('version')!r}")
    unknown = sorted(set(data) - _KEYS)
    if unknown:
        raise SceneError(f"{unknown[0]}: unknown field (known: {', '.join(sorted(_KEYS))})")
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
    sdf = _parse_sdf(data.get("sdf"), root)
    networks = data.get("networks")
    if spec.bundle_kinds and not networks:
        raise SceneError(f"networks: {program} needs a network of kind {' or '.join(map(repr, spec.bundle_kinds))}: "
                         "[{\"bundle\": \"folder\"}]")
    mesh = _parse_mesh(data.get("mesh"), root)
    if sdf is not None and mesh is not None:
        raise SceneError("mesh: a scene has one geometry: \"sdf\" or \"mesh\", not both")
    if spec.geometry == "sdf" and sdf is None:
        raise SceneError(f"sdf: {program} traces an SDF: it needs \"sdf\": \"sdf.json\" or "
                         "{\"network\": \"sdf_bundle\"}")
    if spec.geometry == "mesh" and mesh is None:
        raise SceneError(f"mesh: {program} shades a mesh: it needs \"mesh\": \"mesh.ply\" (OBJ/PLY/GLB) or a "
                         "built-in shape, e.g. {\"shape\": \"teapot\"}")
    if mesh is not None:
        _check_mesh_attributes(mesh, program, spec.mesh_attributes)
    if networks is None and not spec.networks:
        networks = []
    if not isinstance(networks, list) or (not networks and sdf is None and spec.networks):
        raise SceneError("networks: must be a non-empty list of {\"bundle\": ..., \"prefix\": ..., \"output\": ...}")
    refs, prefixes = [], set()
    for i, n in enumerate(networks):
        w = f"networks[{i}]"
        if not isinstance(n, dict) or not isinstance(n.get("bundle"), str):
            raise SceneError(f"{w}.bundle: must name a bundle folder (relative to the scene file)")
        extra = sorted(set(n) - {"bundle", "prefix", "output"})
        if extra:
            raise SceneError(f"{w}.{extra[0]}: unknown field (known: bundle, prefix, output)")
        bpath = (root / n["bundle"]).resolve()
        if not ((bpath / BUNDLE_FILE).is_file() or (bpath.name == BUNDLE_FILE and bpath.is_file())):
            raise SceneError(f"{w}.bundle: no bundle at {bpath}")
        prefix = n.get("prefix", "net")
        if isinstance(sdf, NetworkSdfRef) and prefix == sdf.prefix:
            raise SceneError(f"{w}.prefix: {prefix!r} is the network SDF's prefix (sdf.prefix)")
        if not isinstance(prefix, str) or not prefix.isidentifier() or prefix in prefixes:
            raise SceneError(f"{w}.prefix: must be a unique GLSL identifier, got {prefix!r}")
        prefixes.add(prefix)
        output = n.get("output")
        if output is not None and not isinstance(output, str):
            raise SceneError(f"{w}.output: must be an output port name")
        refs.append(NetworkRef(bpath, prefix, output))
    reference = None
    ref = data.get("reference")
    if ref is not None:
        if isinstance(ref, str):
            ref = {"image": ref}
        if not isinstance(ref, dict) or not isinstance(ref.get("image"), str):
            raise SceneError("reference.image: must name an image file (relative to the scene file)")
        image = (root / ref["image"]).resolve()
        if not image.is_file():
            raise SceneError(f"reference.image: no file {image}")
        colour, space = ref.get("colour", "srgb"), ref.get("space", "field")
        if colour not in ("srgb", "linear"):
            raise SceneError(f"reference.colour: must be \"srgb\" or \"linear\", got {colour!r}")
        _check_image(image, "reference.image", exr=colour == "linear")
        if space not in REFERENCE_SPACES:
            raise SceneError(f"reference.space: must be one of {list(REFERENCE_SPACES)}, got {space!r}")
        reference = Reference(image, colour, space)
    camera = data.get("camera", {"type": "plane2d"})
    _check_camera(camera, "camera")  # validate now: one clear error at load time
    bookmarks = data.get("bookmarks", {})
    if not isinstance(bookmarks, dict):
        raise SceneError("bookmarks: must be an object {name: camera}")
    for k, v in bookmarks.items():
        _check_camera(v, f"bookmarks.{k}")
    lights = _lights(data.get("lights", []))
    environment = data.get("environment")
    if environment is not None and not isinstance(environment, dict):
        raise SceneError("environment: must be an object or null")
    environment_map = None
    if sdf is not None or mesh is not None:
        environment, environment_map = _lit_environment(environment, root)
        need = spec.environment_degree
        if need is not None and environment["degree"] != need:
            raise SceneError(f"environment.degree: {program} uses {need * need} SH coefficients "
                             f"(degree {need}), got {environment['degree']}")
    display = data.get("display", {})
    if not isinstance(display, dict):
        raise SceneError("display: must be an object")
    if not isinstance(display.get("modes", []), list):
        raise SceneError(f"display.modes: must be a list of mode names, got {display.get('modes')!r}")
    try:
        mode = parse_mode(display.get("mode", "final"))
        modes = tuple(parse_mode(m) for m in display.get("modes", [m.name.lower() for m in UI_MODES]))
    except ValueError as exc:
        raise SceneError(f"display: {exc}") from None
    split = display.get("split", 0.5)
    if isinstance(split, bool) or not isinstance(split, (int, float)) or not 0.0 <= split <= 1.0:
        raise SceneError(f"display.split: must be a number in [0, 1], got {split!r}")
    requires = data.get("requires", {})
    if not isinstance(requires, dict):
        raise SceneError("requires: must be an object, e.g. {\"gl\": 330, \"extensions\": []}")
    settings = _settings(data.get("settings", {}), "settings")
    _bind_declared_choices(settings, spec)
    if sdf is not None or mesh is not None:
        _check_sky_settings(settings, environment_map is not None)
    textures = _textures(data.get("textures", []), root)
    try:
        labels = parse_labels(data.get("labels"), settings, [m.label for m in UI_MODES])
    except ValueError as exc:
        raise SceneError(str(exc)) from None
    title = data.get("title", name)
    scene = Scene(textures=textures, name=name, root=root, path=path, program=program, size=tuple(size), networks=refs,
                  camera=camera, reference=reference, title=str(title), bookmarks=bookmarks, lights=lights,
                  environment=environment, display_mode=mode, display_modes=modes, split=float(split),
                  settings=settings, requires=requires, sdf=sdf, environment_map=environment_map,
                  mesh=mesh, labels=labels)
    if spec.validate is not None:
        try:
            spec.validate(scene)
        except ValueError as exc:
            raise SceneError(str(exc)) from None
    return scene


def _parse_sdf(value, root: Path):
    """``"sdf"``: a description file (analytic, geometry/sdf.py) or {"network": bundle folder}."""
    if value is None:
        return None
    if isinstance(value, str):
        from inshade.geometry.sdf import SdfError, load_sdf
        try:
            return load_sdf((root / value).resolve())
        except SdfError as exc:
            raise SceneError(f"sdf: {exc}") from None
    if isinstance(value, dict):
        extra = sorted(set(value) - {"network", "prefix"})
        if extra:
            raise SceneError(f"sdf.{extra[0]}: unknown field (known: network, prefix)")
        if not isinstance(value.get("network"), str):
            raise SceneError("sdf.network: must name a network SDF bundle folder (relative to the scene file)")
        bpath = (root / value["network"]).resolve()
        if not ((bpath / BUNDLE_FILE).is_file() or (bpath.name == BUNDLE_FILE and bpath.is_file())):
            raise SceneError(f"sdf.network: no bundle at {bpath}")
        prefix = value.get("prefix", "sdfnet")
        if not isinstance(prefix, str) or not prefix.isidentifier():
            raise SceneError(f"sdf.prefix: must be a GLSL identifier, got {prefix!r}")
        return NetworkSdfRef(bpath, prefix)
    raise SceneError("sdf: must name an SDF description file or be {\"network\": \"bundle folder\"} "
                     "(relative to the scene file)")


def _parse_mesh(value, root: Path):
    if value is None:
        return None
    if isinstance(value, dict):
        from inshade.geometry.shapes import ShapeError, make_shape
        try:
            name, params, data = make_shape(value, "mesh")
        except ShapeError as exc:
            raise SceneError(str(exc)) from None
        return MeshRef(None, data, name, params)
    if not isinstance(value, str):
        raise SceneError("mesh: must name a mesh file (OBJ/PLY/GLB, relative to the scene file) or a "
                         "built-in shape, e.g. {\"shape\": \"teapot\", \"segments\": 12}")
    from inshade.geometry.gltf import GltfError, load_gltf
    from inshade.geometry.mesh import GLTF_SUFFIXES, MeshError, check_mesh, load_mesh

    path = (root / value).resolve()
    try:
        if path.suffix.lower() in GLTF_SUFFIXES and path.is_file():
            asset = load_gltf(path)   # drawn as the file has it: its normals, tangents and materials
            check_mesh(asset.mesh)
            return MeshRef(path, asset.mesh, gltf=asset)
        return MeshRef(path, load_mesh(path))
    except GltfError as exc:
        raise SceneError(f"mesh: {exc}") from None
    except MeshError as exc:
        raise SceneError(f"mesh: {path}: {exc}" if str(path) not in str(exc) else f"mesh: {exc}") from None


def _check_mesh_attributes(mesh: MeshRef, program: str, needs) -> None:
    """The mesh carries what the program reads (ProgramSpec.mesh_attributes): uv, and tangents that
    are defined somewhere (uv that span an area), else one SceneError naming the mesh and the
    attribute, rather than NaN or arbitrary shading."""
    from inshade.geometry.mesh import MeshError, check_tangents

    if "materials" in needs and mesh.gltf is None:
        raise SceneError(f"mesh: {mesh.name} is not a glTF file, and {program} shades a glTF file's materials "
                         "(give a .gltf or .glb)")
    needs = [a for a in needs if a in ("uv", "tangent")]
    if not needs:
        return
    if mesh_uv(mesh.data) is None:
        raise SceneError(f"mesh: {mesh.name} has no texture coordinates, and {program} needs the mesh "
                         f"attribute{'s' if len(needs) > 1 else ''} {', '.join(needs)} (use an OBJ with vt, "
                         "a PLY/GLB with texture coordinates, or a built-in shape)")
    if "tangent" in needs:
        try:
            check_tangents(mesh.data)
        except MeshError as exc:
            raise SceneError(f"mesh: {mesh.name}: {exc}; {program} needs the mesh attribute tangent") from None


def _lit_environment(env, root: Path) -> tuple[dict, object]:
    """The lighting of an SDF or mesh scene: a procedural sky preset ("sky") or an equirectangular map
    ("map": .exr/.png/.jpg relative to the scene file, projected to SH once here; "sky" is then
    "map"), rotated about +y by "rotation" degrees, its radiance scaled by "intensity". Returns
    (environment, map SH or None)."""
    from inshade.scene.image_io import load_environment
    from inshade.sh import MAX_DEGREE, SKY_PRESETS, project_environment

    given = dict(env or {})
    env = {"sky": "map" if "map" in given else "overcast", "rotation": 0.0, "degree": 4, "intensity": 1.0, **given}
    extra = sorted(set(env) - {"sky", "rotation", "degree", "map", "intensity"})
    if extra:
        raise SceneError(f"environment.{extra[0]}: unknown field (known: degree, intensity, map, rotation, sky)")
    rot = env["rotation"]
    if isinstance(rot, bool) or not isinstance(rot, (int, float)) or not math.isfinite(rot):
        raise SceneError(f"environment.rotation: must be a finite number of degrees, got {rot!r}")
    gain = env["intensity"]
    if isinstance(gain, bool) or not isinstance(gain, (int, float)) or not math.isfinite(gain) or gain < 0:
        raise SceneError(f"environment.intensity: must be a finite number >= 0, got {gain!r}")
    if env["degree"] not in range(1, MAX_DEGREE + 1):
        raise SceneError(f"environment.degree: must be an int in 1..{MAX_DEGREE}, got {env['degree']!r}")
    sh = None
    if "map" in env:
        if not isinstance(env["map"], str):
            raise SceneError("environment.map: must name an equirectangular image (.exr, .png, .jpg)")
        path = (root / env["map"]).resolve()
        try:
            sh = project_environment(load_environment(path), env["degree"])
        except ValueError as exc:   # load_environment names the file and what is wrong with it
            raise SceneError(f"environment.map: {exc}") from None
        env["map"] = str(path)
    if not isinstance(env["sky"], str):
        raise SceneError(f"environment.sky: must be a sky name, got {env['sky']!r}")
    if env["sky"] not in SKY_PRESETS and not (env["sky"] == "map" and sh is not None):
        known = ", ".join([*SKY_PRESETS, *(["map"] if sh is not None else [])])
        raise SceneError(f"environment.sky: unknown sky {env['sky']!r} (known: {known})")
    return env, sh


def _check_sky_settings(settings: dict, has_map: bool) -> None:
    from inshade.sh import SKY_PRESETS

    for name, s in settings.items():
        if s.binding == "environment" and s.target == "sky":
            bad = [c for c in (s.choices or (s.default,))
                   if not isinstance(c, str) or c not in SKY_PRESETS and not (c == "map" and has_map)]
            if bad:
                raise SceneError(f"settings.{name}.choices: unknown sky {bad[0]!r} (known: {', '.join(SKY_PRESETS)}"
                                 f"{', map' if has_map else ''})")


MAX_LIGHTS = 4   # lib/lights.glsl INSHADE_MAX_LIGHTS


# light type -> (its vector field, the class); the kind's index is u_light_kinds' value
# (lib/lights.glsl INSHADE_LIGHT_POINT 0, INSHADE_LIGHT_DIRECTIONAL 1)
LIGHT_TYPES = {"point": ("position", PointLight), "directional": ("direction", DirectionalLight)}
LIGHT_KINDS = tuple(LIGHT_TYPES)


def _lights(data) -> list:
    """scene.json "lights": [{"type": "point", "position": [x, y, z], "intensity": I} or
    {"type": "directional", "direction": [x, y, z] (towards the light), "intensity": I}, ...]."""
    if not isinstance(data, list):
        raise SceneError("lights: must be a list of {\"type\": \"point\", \"position\": [x, y, z], \"intensity\": I} "
                         "or {\"type\": \"directional\", \"direction\": [x, y, z], \"intensity\": I}")
    if len(data) > MAX_LIGHTS:
        raise SceneError(f"lights: at most {MAX_LIGHTS} lights, got {len(data)}")
    out = []
    for i, light in enumerate(data):
        w = f"lights[{i}]"
        if not isinstance(light, dict):
            raise SceneError(f"{w}: must be an object {{\"type\": ..., ...}}")
        kind = light.get("type")
        if not isinstance(kind, str) or kind not in LIGHT_TYPES:
            raise SceneError(f"{w}.type: must be one of {', '.join(map(repr, LIGHT_TYPES))}, got {kind!r}")
        vector, cls = LIGHT_TYPES[kind]
        extra = sorted(set(light) - {"type", vector, "intensity"})
        if extra:
            raise SceneError(f"{w}.{extra[0]}: unknown field for a {kind} light (known: intensity, {vector}, type)")
        vec, power = light.get(vector), light.get("intensity")
        if not (isinstance(vec, list) and len(vec) == 3 and all(_finite(v) for v in vec)):
            raise SceneError(f"{w}.{vector}: must be 3 finite numbers, got {vec!r}")
        vec = tuple(float(v) for v in vec)
        if kind == "directional":
            length = math.sqrt(sum(v * v for v in vec))
            if not length > 1e-12 or not math.isfinite(length):
                raise SceneError(f"{w}.direction: must be a non-zero vector of finite length (towards the light), "
                                 f"got {list(vec)!r}")
            vec = tuple(v / length for v in vec)
        if not _finite(power) or power < 0:
            raise SceneError(f"{w}.intensity: must be a finite number >= 0, got {power!r}")
        out.append(cls(vec, float(power)))
    return out


def light_uniforms(lights) -> dict:
    """lib/lights.glsl's uniforms for ``lights``: u_lights (vec4: position or direction, intensity),
    u_light_kinds (LIGHT_KINDS index), u_scene_light_count; unused slots are zero."""
    import numpy as np

    packed = np.zeros((MAX_LIGHTS, 4), np.float32)
    kinds = np.zeros(MAX_LIGHTS, np.int32)
    for i, light in enumerate(lights):
        packed[i] = (*(light.position if light.kind == "point" else light.direction), light.intensity)
        kinds[i] = LIGHT_KINDS.index(light.kind)
    return {"u_lights": packed.tobytes(), "u_light_kinds": kinds.tobytes(), "u_scene_light_count": len(lights)}


def _finite(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _textures(data, root: Path) -> list:
    if not isinstance(data, list):
        raise SceneError("textures: must be a list of {\"uniform\": ..., \"image\": ...}")
    out = []
    for i, t in enumerate(data):
        w = f"textures[{i}]"
        if not isinstance(t, dict):
            raise SceneError(f"{w}: must be an object")
        extra = sorted(set(t) - TEXTURE_KEYS)
        if extra:
            raise SceneError(f"{w}.{extra[0]}: unknown field (known: {', '.join(sorted(TEXTURE_KEYS))})")
        name = t.get("uniform")
        if not isinstance(name, str) or not name.isidentifier():
            raise SceneError(f"{w}.uniform: must be a GLSL identifier, got {name!r}")
        if not isinstance(t.get("image"), str) or not (root / t["image"]).is_file():
            raise SceneError(f"{w}.image: no image file {t.get('image')!r} (relative to the scene file)")
        aniso = t.get("anisotropy", 1.0)
        if isinstance(aniso, bool) or not isinstance(aniso, (int, float)) or not 1.0 <= aniso <= 16.0:
            raise SceneError(f"{w}.anisotropy: must be a number in [1, 16], got {aniso!r}")
        for key in ("mipmaps", "repeat"):
            if not isinstance(t.get(key, True), bool):
                raise SceneError(f"{w}.{key}: must be true or false")
        _check_image((root / t["image"]).resolve(), f"{w}.image", exr=False)
        out.append(SceneTexture(name, (root / t["image"]).resolve(), t.get("mipmaps", True), float(aniso),
                                t.get("repeat", True)))
    return out


def _check_camera(value, field: str) -> None:
    if not isinstance(value, dict) or not isinstance(value.get("type"), str):
        raise SceneError(f"{field}: must be a camera object with a \"type\" name, got {str(value)[:80]}")
    camera_from_dict(value, field)


def _check_image(path: Path, field: str, exr: bool) -> None:
    """An image file the renderer will read: a readable header of a sane size (image_io), else one
    SceneError naming the field and the file."""
    from .image_io import check_image_file

    try:
        check_image_file(path, exr=exr)
    except ValueError as exc:
        raise SceneError(f"{field}: {exc}") from None


def _settings(data, where: str) -> dict:
    if not isinstance(data, dict):
        raise SceneError(f"{where}: must be an object {{name: setting}}")
    merged = {k: dict(v, exposed=False) for k, v in BUILTIN_SETTINGS.items()}
    for k, v in data.items():
        merged[k] = dict(v, exposed=True) if isinstance(v, dict) else v
    out = {}
    for name, s in merged.items():
        w = f"{where}.{name}"
        if not isinstance(s, dict):
            raise SceneError(f"{w}: must be an object")
        kind = s.get("type")
        if kind not in SETTING_TYPES:
            raise SceneError(f"{w}.type: must be one of {list(SETTING_TYPES)}, got {kind!r}")
        bound = [b for b in BINDINGS if b in s]
        if len(bound) != 1:
            raise SceneError(f"{w}: needs exactly one of {list(BINDINGS)} (what the value drives)")
        binding = bound[0]
        target = s[binding]
        if not isinstance(target, str) or not (target.isidentifier() or binding == "codegen"):
            raise SceneError(f"{w}.{binding}: must be an identifier, got {target!r}")
        if binding == "environment" and target not in ENVIRONMENT_TARGETS:
            raise SceneError(f"{w}.environment: must be one of {list(ENVIRONMENT_TARGETS)}, got {target!r}")
        if binding == "codegen" and target not in CODEGEN_OPTIONS:
            raise SceneError(f"{w}.codegen: unknown codegen option {target!r} (known: {', '.join(CODEGEN_OPTIONS)})")
        extra = sorted(set(s) - {"type", "default", "min", "max", "choices", "label", "exposed", *BINDINGS})
        if extra:
            raise SceneError(f"{w}.{extra[0]}: unknown field")
        lo, hi = s.get("min"), s.get("max")
        for key, v in (("min", lo), ("max", hi)):
            if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float))):
                raise SceneError(f"{w}.{key}: must be a number")
        if kind in ("float", "int") and (lo is None or hi is None or lo > hi):
            raise SceneError(f"{w}: a {kind} setting needs a range: \"min\" <= \"max\"")
        choices = s.get("choices", [])
        if not isinstance(choices, list):
            raise SceneError(f"{w}.choices: must be a list, got {choices!r}")
        choices = tuple(choices)
        if kind == "choice":
            if not choices:
                raise SceneError(f"{w}.choices: a choice setting needs a non-empty list")
            if binding == "codegen":
                bad = [c for c in choices if c not in CODEGEN_OPTIONS[target]]
                if bad:
                    raise SceneError(f"{w}.choices: {bad[0]!r} is not a {target} option "
                                     f"({', '.join(CODEGEN_OPTIONS[target])})")
        setting = Setting(name, kind, s.get("default"), binding, target, lo, hi, choices,
                          str(s.get("label", name)), bool(s.get("exposed", True)))
        if "default" not in s:
            raise SceneError(f"{w}.default: missing")
        setting.default = setting.check(s["default"], f"{w}.default:")
        out[name] = setting
    return out


def _bind_declared_choices(settings: dict, spec: technique.ProgramSpec) -> None:
    """Settings bound to a uniform or define the program declares a choice for
    (``ProgramSpec.choices``) name only declared values and drive the declared index: a choice
    lists declared names (or declared indices: the index form of a define), an int setting's
    range holds declared indices only."""
    for name, s in settings.items():
        choice = spec.choice(s.target) if s.binding in ("uniform", "define") else None
        if choice is None:
            continue
        w = f"settings.{name}"
        known = ", ".join(choice.values)
        if s.type == "choice":
            bad = [c for c in s.choices if c not in choice.values
                   and not (type(c) is int and c in choice.indices)]
            if bad:
                raise SceneError(f"{w}.choices: {bad[0]!r} is not a {s.target} value of {spec.program} "
                                 f"(known: {known})")
        elif s.type == "int":
            bad = [i for i in range(int(s.min), int(s.max) + 1) if i not in choice.indices]
            if bad:
                raise SceneError(f"{w}: {bad[0]} is not a {s.target} index of {spec.program} "
                                 f"(known: {', '.join(f'{v} {i}' for v, i in zip(choice.values, choice.indices))})")
        else:
            raise SceneError(f"{w}.type: {s.target} is a choice of {spec.program} ({known}): "
                             f"a {s.type} setting cannot drive it")
        s.declared = choice


def _where(bundle) -> str:
    return str(bundle.path) if bundle.path is not None else "<bundle in memory>"
