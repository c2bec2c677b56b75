"""What a 3D scene draws: ``"sdf"`` (an analytic description file, geometry/sdf.py, or a network
SDF bundle, codegen/network_sdf.py) or ``"mesh"`` (a mesh file, geometry/mesh.py, or a built-in
shape, geometry/shapes.py), checked against what the program needs (``ProgramSpec.geometry`` and
``mesh_attributes``)."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from inshade import technique
from inshade.geometry.mesh import mesh_uv

from .common import SceneError, is_bundle


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


def parse_sdf(value, root: Path):
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
        if not is_bundle(bpath):
            raise SceneError(f"sdf.network: no bundle at {bpath}")
        prefix = value.get("prefix", "sdfnet")
        if not isinstance(prefix, str) or not prefix.isidentifier():
            raise SceneError(f"sdf.prefix: must be a GLSL identifier, got {prefix!r}")
        return NetworkSdfRef(bpath, prefix)
    raise SceneError("sdf: must name an SDF description file or be {\"network\": \"bundle folder\"} "
                     "(relative to the scene file)")


def parse_mesh(value, root: Path):
    """``"mesh"``: a mesh file (OBJ/PLY, or glTF with its materials) or a built-in shape."""
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


def check_geometry(sdf, mesh: MeshRef | None, spec: technique.ProgramSpec) -> None:
    """One geometry, the one the program draws over, carrying what the program reads."""
    program = spec.program
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
