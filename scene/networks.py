"""The networks a scene draws: ``"networks"`` (bundle folders, each with its GLSL prefix and the
output port shown), and the ``render`` field of a bundle drawn on its own (the format before
scene.json existed)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from inshade import technique

from .common import MAX_SIZE, SceneError, is_bundle
from .geometry_ref import NetworkSdfRef


@dataclass
class NetworkRef:
    bundle: Path              # bundle folder (or bundle.json)
    prefix: str = "net"       # GLSL symbol prefix; the chunk is <network> for "net", <network_P> otherwise
    output: str | None = None  # the output port the program shows (None: the first)

    @property
    def chunk(self) -> str:
        return "network" if self.prefix == "net" else f"network_{self.prefix}"


def parse_networks(networks, root: Path, spec: technique.ProgramSpec, sdf) -> list[NetworkRef]:
    """``"networks"``: bundles relative to the scene file, with unique prefixes (none the network
    SDF's). A program that draws no network may leave the field out; one that draws networks may
    have none only when a network SDF is what it draws."""
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
        if not is_bundle(bpath):
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
    return refs


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


def _where(bundle) -> str:
    return str(bundle.path) if bundle.path is not None else "<bundle in memory>"
