"""The technique plug-in contract: one record per technique, found by name.

A technique (a paper's method, e.g. learnt-transfer PRT) is one folder under ``techniques/``
holding its record, its torch side (trainer, twin, asset builder), its bench and its GLSL. The
record is a ``Technique``: what it is, which bundle kinds it reads, which programs it draws and
what each program needs from the runtime (``ProgramSpec``). The CLI (``inshade train NAME``,
``inshade bench NAME``), the runtime and the viewer read the registry; none of them names a
technique.

Records are torch-free: entry points are module names imported only when run, and the hooks a
program spec carries (extra chunks, per-frame uniforms, validation) import numpy-side code only.

Registering: built-in techniques are listed in ``inshade.techniques.BUILTIN`` (one line each).
Out-of-tree techniques are folders named in ``INSHADE_TECHNIQUES`` (``os.pathsep``-separated):
each is imported as a package (its parent folder joins ``sys.path``) and must define
``TECHNIQUE``. ``register()`` adds a record at run time (tests).
"""
from __future__ import annotations

import hashlib
import importlib
import os
import sys
from collections.abc import Callable, Hashable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from inshade.shaders.library import add_search_provider

PLUGINS_ENV = "INSHADE_TECHNIQUES"
# What a program draws over; the runtime sets up the matching pass (scene/geometry_ref.py check_geometry).
GEOMETRIES = ("fullscreen", "sdf", "mesh")
MESH_ATTRIBUTES = ("uv", "tangent", "materials")   # materials: a glTF mesh's (lib/gltf_material)


class TechniqueError(ValueError):
    """An unknown technique or program, or a record that breaks the contract."""


@dataclass(frozen=True)
class Paper:
    title: str
    venue: str
    arxiv: str | None = None      # arXiv id, e.g. "2305.02678"; None when there is none
    doi: str | None = None

    def cite(self) -> str:
        ids = [f"arXiv:{self.arxiv}"] * bool(self.arxiv) + [f"doi:{self.doi}"] * bool(self.doi)
        return f"{self.title} ({', '.join([self.venue, *ids])})"


# The generated chunk of a program's declared choices (ProgramSpec.choices): the pass includes it.
CHOICES_CHUNK = "choices"


@dataclass(frozen=True)
class Choice:
    """An enumeration a program reads as an int, declared once.

    ``target`` is the uniform (or ``#define``) a scene setting binds, ``prefix`` the GLSL name
    prefix, ``values`` the names in index order (a sequence) or ``{name: index}`` (a mapping, for
    indices with gaps or an offset). The runtime writes ``#define PREFIX_NAME index`` for each into
    the chunk ``<choices>`` and sets the uniform (or define) to the declared index of the
    setting's value, so the Python table, the GLSL names and the scene cannot disagree.
    """
    target: str
    prefix: str
    values: tuple
    indices: tuple = field(init=False, default=())   # each value's int, in ``values`` order

    def __post_init__(self):
        where = f"choice {self.target!r}"
        if isinstance(self.values, str):
            raise TechniqueError(f"{where}: values must be a sequence or a mapping of names, got {self.values!r}")
        table = dict(self.values) if isinstance(self.values, Mapping) else {v: i for i, v in enumerate(self.values)}
        if not (isinstance(self.target, str) and self.target.isidentifier()):
            raise TechniqueError(f"{where}: target must be a uniform or define name, got {self.target!r}")
        if not (isinstance(self.prefix, str) and self.prefix.isidentifier() and self.prefix.isupper()):
            raise TechniqueError(f"{where}: prefix must be an upper-case GLSL name, got {self.prefix!r}")
        if not table:
            raise TechniqueError(f"{where}: needs at least one value")
        for name, index in table.items():
            if not (isinstance(name, str) and name.isidentifier() and name.islower()):
                raise TechniqueError(f"{where}: values must be lower-case identifiers, got {name!r}")
            if isinstance(index, bool) or not isinstance(index, int) or index < 0:
                raise TechniqueError(f"{where}: {name!r}: index must be an int >= 0, got {index!r}")
        if len(set(table.values())) != len(table):
            raise TechniqueError(f"{where}: two values share an index: {table}")
        object.__setattr__(self, "values", tuple(table))
        object.__setattr__(self, "indices", tuple(table.values()))

    def index(self, value: str) -> int:
        """The int ``value`` drives (ValueError if it is not declared)."""
        return self.indices[self.values.index(value)]

    def defines(self) -> dict[str, int]:
        """{GLSL name: index}, e.g. {"PBR_VIEW_DI": 1}."""
        return {f"{self.prefix}_{v.upper()}": i for v, i in zip(self.values, self.indices)}


def choice_chunks(spec: ProgramSpec) -> dict[str, str]:
    """``{"choices": source}``: the ``#define`` lines of the program's declared choices ({} if none)."""
    if not spec.choices:
        return {}
    lines = [f"// {spec.program}'s choices (generated from its ProgramSpec.choices)"]
    for choice in spec.choices:
        lines += [f"#define {name} {index}" for name, index in choice.defines().items()]
    return {CHOICES_CHUNK: "\n".join(lines) + "\n"}


def prefixed_bundle(bundles, networks, prefix: str, program: str, what: str = ""):
    """The loaded bundle of the scene's network at ``prefix``: a program's hooks get the bundles and
    the networks side by side. ``what`` names the network in the error."""
    for bundle, net in zip(bundles, networks):
        if net.prefix == prefix:
            return bundle
    raise ValueError(f"networks: {program} needs one network with prefix \"{prefix}\"" + (f" ({what})" if what else ""))


@dataclass(frozen=True)
class FrameInputs:
    """What a program's per-frame hook sees: the scene, the current setting values, and the
    environment's radiance SH [K, 3] float32 (lit scenes; else None)."""
    scene: object
    values: Mapping
    environment_sh: object = None


@dataclass(frozen=True)
class ProgramSpec:
    """One fragment program a technique draws, and what it needs from the runtime.

    - ``program``: the entry chunk (``passes/<name>.frag``), unique over all techniques;
    - ``geometry``: what the pass covers: ``fullscreen`` (a field or an analytic scene in the
      shader), ``sdf`` (a sphere-traced SDF: the scene's ``sdf``), ``mesh`` (a rasterised G-buffer
      of the scene's ``mesh``, shaded once per pixel); ``mesh_attributes`` the mesh must carry
      (``uv``, ``tangent``, ``materials``: the mesh is a glTF file whose materials the runtime
      uploads for shaders/lib/gltf_material.glsl, runtime/materials.py);
    - ``networks``: False for a program that draws no network (a reference shading of the scene
      alone); such a scene may have ``"networks": []``;
    - ``attachments``: colour outputs the program writes (RGBA32F each; location 0 is what the
      display pass shows, the others are data a caller reads back, e.g. a sampler's inputs);
    - ``field_inputs``: a bundle's ``render.program`` may name this program; the bundle's only
      input must be this wide (None: scenes only);
    - ``bundle_kinds``: the scene's networks must include one bundle of one of these kinds;
    - ``uniforms``: values set every frame unless a scene setting binds them (a program shared
      through a program cache never keeps another scene's values);
    - ``chunks(scene, bundles, networks, codegen_options) -> {name: source}``: generated chunks
      besides the networks' own;
    - ``frame(FrameInputs) -> {uniform: value}``: per-frame CPU work (e.g. a light matrix);
    - ``validate(scene)``: raise ``ValueError`` with a field-naming message if the scene cannot
      be drawn by this program (checked when the scene loads);
    - ``environment_degree``: the SH degree the program's lighting needs (None: any);
    - ``visibility``: (mesh) the G-buffer also holds a visibility buffer, the face index
      (``usampler2D u_gbuffer_primitive``, R32UI) and barycentrics (``u_gbuffer_barycentric``,
      RG32F: t0, t1 of the face's vertices 0, 1), for a pass that decodes per (triangle,
      barycentric) point (runtime/geometry.py);
    - ``accumulate``: a stochastic program drawing one Monte Carlo sample per pixel per draw. It
      gets ``uniform int u_sample_index`` (0, 1, 2, ... since the last reset; hash it with the
      pixel: shaders/lib/random.glsl) and the runtime shows the running mean of its samples over
      all attachments, restarting whenever the draw's inputs change (camera, size, settings,
      weights, program); ``inshade render --spp N`` draws N samples;
    - ``shadows(scene, bundles, values) -> ShadowRequest | None``: shadow maps of directional
      lights (runtime/shadow.py; ``values`` = the scene's current setting values). Called before
      every network draw (keep it cheap: cache the caster mesh); the renderer redraws the maps only
      when the request's key, directions or size change, and binds ``u_shadow_map``,
      ``u_shadow_matrix`` and ``u_shadow_layers`` of shaders/lib/shadow_map.glsl (None: no layers,
      ``shadow_visibility`` is 1);
    - ``bake(scene, values, size) -> MaterialBake``: (mesh) the material the program decodes, baked
      by the GL runtime into a ``size`` x ``size`` texture over a rectangle of the mesh's uv: what
      ``inshade export-gltf`` writes as the material's textures;
    - ``channels``: (mesh) a ``MaterialChannels``: the material it decodes, per fragment, for a host's
      own shading;
    - ``choices``: the program's enumerations (``Choice``: a uniform or define, a GLSL prefix, the
      values in index order). The runtime generates the chunk ``<choices>`` (``#define
      PREFIX_VALUE index`` each) for the pass to include, checks that a scene setting bound to the
      target names only declared values, and sets the declared index.
    """
    program: str
    geometry: str = "fullscreen"
    mesh_attributes: tuple[str, ...] = ()
    networks: bool = True
    attachments: int = 1
    field_inputs: int | None = None
    bundle_kinds: tuple[str, ...] = ()
    uniforms: Mapping = field(default_factory=dict)
    chunks: Callable | None = None
    frame: Callable | None = None
    validate: Callable | None = None
    environment_degree: int | None = None
    visibility: bool = False
    accumulate: bool = False
    shadows: Callable | None = None
    choices: tuple[Choice, ...] = ()
    bake: Callable | None = None
    channels: MaterialChannels | None = None

    def __post_init__(self):
        if self.geometry not in GEOMETRIES:
            raise TechniqueError(f"program {self.program}: geometry must be one of {list(GEOMETRIES)}, "
                                 f"got {self.geometry!r}")
        if not isinstance(self.attachments, int) or self.attachments < 1:
            raise TechniqueError(f"program {self.program}: attachments must be an int >= 1, got {self.attachments!r}")
        if self.visibility and self.geometry != "mesh":
            raise TechniqueError(f"program {self.program}: visibility is a mesh G-buffer option (geometry 'mesh')")
        bad = [a for a in self.mesh_attributes if a not in MESH_ATTRIBUTES]
        if bad:
            raise TechniqueError(f"program {self.program}: unknown mesh attribute {bad[0]!r} "
                                 f"(known: {', '.join(MESH_ATTRIBUTES)})")
        self._check_choices()

    def _check_choices(self):
        if not all(isinstance(c, Choice) for c in self.choices):
            raise TechniqueError(f"program {self.program}: choices must be Choice records")
        targets = [c.target for c in self.choices]
        twice = sorted({t for t in targets if targets.count(t) > 1})
        if twice:
            raise TechniqueError(f"program {self.program}: two choices drive {twice[0]!r}")
        names = [name for c in self.choices for name in c.defines()]
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise TechniqueError(f"program {self.program}: two choices generate {twice[0]}")

    def choice(self, target: str) -> Choice | None:
        """The declared choice a setting bound to ``target`` drives, or None."""
        return next((c for c in self.choices if c.target == target), None)


@dataclass
class MaterialBake:
    """A decoded material as textures (``ProgramSpec.bake``): ``channels`` {name: [S, S(, k)] float},
    named as geometry/gltf_sample.py ``material_channels`` (linear base_color, metallic, roughness,
    tangent-space normal, occlusion, emissive, alpha), row 0 = the top of the texture; the texture
    covers the mesh uv rectangle ``origin`` + [0, 1]^2 * ``extent`` (v up), wrapping along the axes
    ``repeat`` says and clamped along the others; ``material``: the glTF material of the scene's
    mesh it replaces (the others stay the file's), or None for the whole mesh."""
    channels: Mapping
    origin: tuple = (0.0, 0.0)
    extent: tuple = (1.0, 1.0)
    repeat: tuple = (True, True)
    material: int | None = None


@dataclass(frozen=True)
class MaterialChannels:
    """What a mesh program's network decodes per fragment as a glTF material's channels, for a host
    that shades them itself (``inshade export-three``: three.js's own PBR): ``chunk`` names a library
    chunk in GLSL (.glsl) and WGSL (.wgsl) defining ``material_channels(uv)`` (lib/material_channels:
    linear base colour, tangent-space normal, roughness, occlusion, metallic) at a fragment's TEXCOORD_0
    from the network (prefix "net"); ``chunks(bundle, language)`` generates the chunks it needs
    besides the network ("glsl" or "wgsl"); ``material(bundle)`` is the index of the glTF material
    whose surfaces it decodes."""
    chunk: str
    chunks: Callable
    material: Callable


@dataclass
class ShadowRequest:
    """What to shadow: a caster mesh (``vertices`` float32 [V, 3], ``faces`` uint32 [F, 3]), light
    ``directions`` float32 [L, 3] (unit, from the scene toward the light), the map's side ``size``
    in texels, and a hashable ``key`` naming the mesh (the same key = the same mesh: not re-uploaded;
    None = a digest of the arrays)."""

    vertices: np.ndarray
    faces: np.ndarray
    directions: np.ndarray
    size: int = 1024
    key: Hashable = None

    def __post_init__(self):
        self.vertices = np.ascontiguousarray(self.vertices, np.float32)
        if self.vertices.ndim != 2 or self.vertices.shape[1] != 3 or not len(self.vertices):
            raise ValueError(f"ShadowRequest.vertices: expected [V, 3] with V >= 1, got {list(self.vertices.shape)}")
        if not np.isfinite(self.vertices).all():
            raise ValueError("ShadowRequest.vertices: not finite")
        faces = np.asarray(self.faces)
        if faces.ndim != 2 or faces.shape[1] != 3 or not np.issubdtype(faces.dtype, np.integer):
            raise ValueError(f"ShadowRequest.faces: expected integer [F, 3], got {faces.dtype} {list(faces.shape)}")
        if faces.size and (faces.min() < 0 or faces.max() >= len(self.vertices)):
            raise ValueError(f"ShadowRequest.faces: indices must lie in 0..{len(self.vertices) - 1}")
        self.faces = np.ascontiguousarray(faces, np.uint32)
        self.directions = np.ascontiguousarray(self.directions, np.float32)
        if self.directions.ndim != 2 or self.directions.shape[1] != 3 or not len(self.directions):
            raise ValueError(f"ShadowRequest.directions: expected [L, 3] with L >= 1, "
                             f"got {list(self.directions.shape)}")
        norms = np.linalg.norm(self.directions.astype(np.float64), axis=1)
        if not (np.abs(norms - 1.0) < 1e-3).all():
            raise ValueError(f"ShadowRequest.directions: must be unit vectors, got lengths {norms.round(4).tolist()}")
        if isinstance(self.size, bool) or not isinstance(self.size, (int, np.integer)) or self.size < 1:
            raise ValueError(f"ShadowRequest.size: must be an int >= 1, got {self.size!r}")
        self.size = int(self.size)
        if self.key is None:
            self.key = hashlib.sha1(self.vertices.tobytes() + self.faces.tobytes()).hexdigest()
        hash(self.key)   # TypeError here, not later, for an unhashable key


@dataclass(frozen=True)
class Technique:
    """A technique's record: see the module docstring.

    ``kinds`` are the bundle kinds its trainers write (new bundles); ``old_kinds`` maps kinds
    that earlier bundles carry to the current one, and they are still read. ``train`` and
    ``bench`` name modules with ``main(argv) -> int`` (imported only when run: they may need
    torch). ``shaders`` is the folder whose chunks join the shader search path. ``converts`` maps
    file suffixes ``inshade convert`` reads into this technique's assets to the module that does it
    (``convert(source, folder, *, force, quiet) -> str``, the line said when done; ``SOURCE``: what
    such a file is, in words).
    ``opens`` maps file suffixes that ``inshade render`` / ``view`` / ``info`` take as a scene
    to a function ``(path) -> scene.json data`` (e.g. a glTF file drawn by a reference pass).
    """
    name: str
    summary: str
    paper: Paper | None = None
    kinds: tuple[str, ...] = ()
    old_kinds: Mapping = field(default_factory=dict)
    programs: tuple[ProgramSpec, ...] = ()
    train: str | None = None
    train_help: str = ""
    train_alias: str | None = None   # a top-level command that is `inshade train NAME` (e.g. compress)
    bench: str | None = None
    bench_help: str = ""
    shaders: Path | None = None
    converts: Mapping = field(default_factory=dict)
    opens: Mapping = field(default_factory=dict)

    def __post_init__(self):
        if not self.name.isidentifier():
            raise TechniqueError(f"technique name must be an identifier, got {self.name!r}")
        if self.train_alias is not None and not (self.train and self.train_alias.isidentifier()):
            raise TechniqueError(f"technique {self.name!r}: train_alias needs a trainer and an identifier, "
                                 f"got {self.train_alias!r}")


def folder_fields(package: str, *, train: str | None = None, bench: str | None = None,
                  shaders: bool = False) -> dict:
    """A record's fields that follow from its folder, for ``Technique(**folder_fields(__name__, ...))``:
    the ``train`` / ``bench`` modules beside the package's ``__init__`` (given: their help lines) and
    its ``shaders/`` folder, so a record never spells its own folder's name."""
    fields = {}
    if train is not None:
        fields.update(train=f"{package}.train", train_help=train)
    if bench is not None:
        fields.update(bench=f"{package}.bench", bench_help=bench)
    if shaders:
        fields["shaders"] = Path(sys.modules[package].__file__).resolve().parent / "shaders"
    return fields


def folder_technique(package: str, summary: str, paper: Paper | None = None, *, train: str | None = None,
                     bench: str | None = None, **record) -> Technique:
    """The record of the technique folder ``package`` (pass ``__name__``): named after the folder,
    writing bundles of that kind unless ``kinds`` says otherwise, with the fields ``folder_fields``
    finds beside it (its ``shaders/`` folder where it has one) and the others as given."""
    name = package.rpartition(".")[2]
    shaders = (Path(sys.modules[package].__file__).resolve().parent / "shaders").is_dir()
    return Technique(name=name, summary=summary, paper=paper, **{"kinds": (name,), **record},
                     **folder_fields(package, train=train, bench=bench, shaders=shaders))


_REGISTRY: dict[str, Technique] = {}
_LOADED = False


def register(technique: Technique) -> Technique:
    """Add a record. A name, program or bundle kind that another technique already has is an error."""
    if not isinstance(technique, Technique):
        raise TechniqueError(f"register: expected a Technique, got {type(technique).__name__}")
    old = _REGISTRY.get(technique.name)
    if old is not None and old is not technique:
        raise TechniqueError(f"technique {technique.name!r} is registered twice")
    for other in _REGISTRY.values():
        if other.name == technique.name:
            continue
        programs = {p.program for p in other.programs} & {p.program for p in technique.programs}
        if programs:
            raise TechniqueError(f"technique {technique.name!r}: program {sorted(programs)[0]} already "
                                 f"belongs to {other.name!r}")
        kinds = set(_all_kinds(other)) & set(_all_kinds(technique))
        if kinds:
            raise TechniqueError(f"technique {technique.name!r}: bundle kind {sorted(kinds)[0]!r} already "
                                 f"belongs to {other.name!r}")
        suffixes = set(other.converts) & set(technique.converts)
        if suffixes:
            raise TechniqueError(f"technique {technique.name!r}: inshade convert's {sorted(suffixes)[0]} files "
                                 f"already belong to {other.name!r}")
        suffixes = set(other.opens) & set(technique.opens)
        if suffixes:
            raise TechniqueError(f"technique {technique.name!r}: {sorted(suffixes)[0]} files already open as "
                                 f"{other.name!r} scenes")
        if technique.train_alias and technique.train_alias in (other.name, other.train_alias):
            raise TechniqueError(f"technique {technique.name!r}: train_alias {technique.train_alias!r} already "
                                 f"names {other.name!r}")
    _REGISTRY[technique.name] = technique
    return technique


def unregister(name: str) -> None:
    _REGISTRY.pop(name, None)


def _all_kinds(t: Technique) -> list[str]:
    return [*t.kinds, *t.old_kinds]


def _load() -> None:
    """Import the built-in records, then the plug-in folders of ``INSHADE_TECHNIQUES`` (once)."""
    global _LOADED
    if _LOADED:
        return
    _LOADED = True
    from inshade import techniques as builtin

    for name in builtin.BUILTIN:
        register(importlib.import_module(f"inshade.techniques.{name}").TECHNIQUE)
    for folder in filter(None, os.environ.get(PLUGINS_ENV, "").split(os.pathsep)):
        load_folder(folder)


def load_folder(folder) -> Technique:
    """Import a technique folder (a package whose ``__init__`` defines ``TECHNIQUE``) and register it."""
    folder = Path(folder).resolve()
    if not (folder / "__init__.py").is_file():
        raise TechniqueError(f"{PLUGINS_ENV}: {folder}: not a technique folder (no __init__.py)")
    if str(folder.parent) not in sys.path:
        sys.path.insert(0, str(folder.parent))
    module = importlib.import_module(folder.name)
    record = getattr(module, "TECHNIQUE", None)
    if not isinstance(record, Technique):
        raise TechniqueError(f"{PLUGINS_ENV}: {folder}: defines no TECHNIQUE record")
    return register(record)


def techniques() -> list[Technique]:
    """Every registered technique, in registration order."""
    _load()
    return list(_REGISTRY.values())


def get(name: str) -> Technique:
    _load()
    if name not in _REGISTRY:
        raise TechniqueError(f"unknown technique {name!r} (known: {', '.join(_REGISTRY)})")
    return _REGISTRY[name]


def program_spec(program: str) -> tuple[Technique, ProgramSpec]:
    """The technique that draws ``program`` and its spec."""
    _load()
    for t in _REGISTRY.values():
        for spec in t.programs:
            if spec.program == program:
                return t, spec
    known = sorted(p.program for t in _REGISTRY.values() for p in t.programs)
    raise TechniqueError(f"no technique draws program {program!r} (known: {', '.join(known)})")


def opener(suffix: str) -> Callable | None:
    """The function that makes scene data of a file with this suffix (``Technique.opens``), or None."""
    _load()
    return next((t.opens[suffix.lower()] for t in _REGISTRY.values() if suffix.lower() in t.opens), None)


def technique_of_kind(kind: str) -> Technique | None:
    """The technique whose bundles carry ``kind`` (current or old), or None."""
    _load()
    for t in _REGISTRY.values():
        if kind in t.kinds or kind in t.old_kinds:
            return t
    return None


def current_kind(kind: str) -> str:
    """``kind`` with an old name mapped to the current one (unknown kinds unchanged)."""
    t = technique_of_kind(kind)
    return t.old_kinds.get(kind, kind) if t is not None else kind


def shader_roots() -> list[Path]:
    """The technique shader folders, in registration order (the chunk resolver searches them)."""
    return [t.shaders for t in techniques() if t.shaders is not None]


add_search_provider(shader_roots)     # technique chunks resolve by name wherever programs are assembled
