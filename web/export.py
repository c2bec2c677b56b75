"""``inshade export-web ASSET -o DIR``: an asset as a static WebGL2 page (and WebGPU: ``--api``).

The asset is set up through the GL runtime (``SceneRenderer``: programs generated and compiled, the
environment built, shadow maps drawn) with GLSL ES 3.00 programs planned against WebGL2's limits
(``limits.WEBGL2``); what its draw would bind is then written for the page to replay, so the page
and ``inshade render`` run the same programs on the same data:

- ``programs/*.glsl``: every pass assembled by the resolver (scene, display, present, and where the
  scene needs them the G-buffer, the accumulation and the network evaluation pass);
- ``data.bin`` + ``manifest.json``: textures (network resources, scene textures, the environment's
  importance-sampling textures, shadow maps, a linear reference) and uniform blocks as raw texels,
  the mesh's vertex attributes, the evaluation batch; uniforms the page does not compute itself;
  the settings as controls; ``reference.png``: an sRGB reference image;
- ``index.html``, ``evaluate.html``, ``inshade.js``: the page (no framework, no build step);
- with ``api`` webgpu or auto, ``programs/*.wgsl``: the same programs as WGSL (``webgpu.translate``),
  drawn by ``webgpu_backend.js``.

What the page computes: the camera's uniforms (orbit / zoom / pan), the uniforms a setting binds,
the display pass's and the accumulation's. What it takes as data, fixed at the exported settings:
per-frame CPU work of a technique (``ProgramSpec.frame``), shadow maps, the environment; a setting
that changes any of them, or that is compiled in (a define or a codegen option), is shown as fixed
and can be chosen at export with ``--set NAME=VALUE``.
"""
from __future__ import annotations

import hashlib
import io
import json
import logging
import shutil
from pathlib import Path

import numpy as np
from PIL import Image

from inshade.codegen import generate
from inshade.codegen.glsl import TextureResource, UniformBlockResource
from inshade.codegen.limits import LimitError
from inshade.codegen.targets import TargetError
from inshade.runtime.context import shared_context
from inshade.runtime.environment import ENV_UNIFORMS
from inshade.runtime.geometry import FRAGMENT as GBUFFER_FRAGMENT, VERTEX as MESH_VERTEX, cutout_chunks, \
    gbuffer_attributes, gbuffer_layout
from inshade.runtime.network import texture_levels
from inshade.runtime.renderer import VERTEX, SceneRenderer
from inshade.runtime.scene_passes import BLEND_LAYER_READS
from inshade.scene.description import load_scene
from inshade.scene.display import UI_MODES, glsl_chunk, parse_mode
from inshade.scene.tonemap import TONEMAPPED_MODES
from inshade.scene.tonemap import glsl_chunk as tonemap_chunk
from inshade.shaders import assemble
from inshade.technique import FrameInputs

from .folders import claim_folder, write_folder
from .limits import BASE_EXTENSIONS, TEXTURE_EXTENSIONS, WEBGL2, WebLimitError

log = logging.getLogger("inshade")

FORMAT = "inshade-web 1"
TARGET = "es300"
PAGE = Path(__file__).resolve().parent / "page"
PAGE_FILES = ("index.html", "evaluate.html", "inshade.js", "evaluate_webgpu.html", "webgpu.js", "webgpu_backend.js")
APIS = {"webgl2": ["webgl2"], "webgpu": ["webgpu"], "auto": ["webgpu", "webgl2"]}   # the page tries them in order
MANIFEST, DATA, REFERENCE_PNG = "manifest.json", "data.bin", "reference.png"
EVAL_BATCH = 1024          # samples in the evaluation page's batch
EVAL_UINT_RANGE = 256      # uint lanes of the batch are ids 0..255 (tables hold at least that many rows)
UNIT_SEMANTICS = ("normal", "direction")   # ports whose batch rows are unit vectors (the rest: [0, 1))
ALIGN = 16


class _Blob:
    """The bytes of data.bin; ``add`` returns [offset, nbytes] of an array (16-byte aligned). The
    same bytes added twice are stored once (e.g. a network's tables in the viewer and the evaluation)."""

    def __init__(self):
        self.parts, self.size, self.seen = [], 0, {}

    def add(self, array) -> list[int]:
        data = array if isinstance(array, bytes) else np.ascontiguousarray(array).tobytes()
        digest = hashlib.sha256(data).digest()
        if digest in self.seen:
            return list(self.seen[digest])
        pad = -self.size % ALIGN
        self.parts.append(b"\0" * pad + data)
        self.size += pad
        at = self.size
        self.size += len(data)
        self.seen[digest] = (at, len(data))
        return [at, len(data)]

    def bytes(self) -> bytes:
        return b"".join(self.parts)


def _texture(blob: _Blob, uniform: str, res: TextureResource, *, generate_mipmaps: bool = False,
             anisotropy: float = 1.0) -> dict:
    """A texture record: kind, size [w, h, depth or layers], channels, dtype, filter, wrap and the
    levels' [offset, nbytes] (texel (x, y) of level k = row y of its array: data orientation)."""
    levels = texture_levels(res)
    shape = levels[0].shape
    kind = "2d_array" if res.array else "3d" if res.dims == 3 else "2d"
    size = [shape[1], shape[0], 1] if kind == "2d" else [shape[2], shape[1], shape[0]]
    return {"uniform": uniform, "kind": kind, "size": [int(v) for v in size], "channels": int(shape[-1]),
            "dtype": res.dtype, "filter": res.filter, "wrap": res.wrap,
            "levels": [blob.add(a) for a in levels], "generate_mipmaps": generate_mipmaps,
            "anisotropy": float(anisotropy)}


def _uniform_value(value, fmt: str = "f"):
    """A uniform as the page sets it: a flat list of numbers. Bytes are read as the uniform's GLSL
    type stores them (moderngl's ``fmt``: ``i`` int32, ``I`` uint32, else float32)."""
    if isinstance(value, bytes):
        dtype = {"i": np.int32, "I": np.uint32}.get(fmt[-1:], np.float32)
        return np.frombuffer(value, dtype).tolist()
    if isinstance(value, (bool, np.bool_)):
        return [int(value)]
    if isinstance(value, (int, float, np.integer, np.floating)):
        return [value.item() if hasattr(value, "item") else value]
    return [float(v) for v in np.asarray(value, np.float64).reshape(-1)]


def _extensions(textures: list[dict]) -> list[str]:
    need = list(BASE_EXTENSIONS)
    for t in textures:
        ext = TEXTURE_EXTENSIONS.get((t["dtype"], t["filter"] == "linear"))
        if ext and ext not in need:
            need.append(ext)
    return need


class WebExport:
    """The page of one scene at its settings; ``write(folder)`` puts it on disk."""

    def __init__(self, source, *, settings: dict | None = None, width: int | None = None,
                 height: int | None = None, eval_count: int = EVAL_BATCH, api: str = "webgl2"):
        self.scene = load_scene(source)
        self.eval_count = int(eval_count)
        self.source = Path(source)
        scene = self.scene
        ctx = shared_context()
        try:
            self.renderer = SceneRenderer(scene, ctx, settings={"labels": False, **(settings or {})},
                                          limits=WEBGL2, target=TARGET)
        except LimitError as exc:
            raise WebLimitError(f"WebGL2: {exc}") from None
        self.width = scene.size[0] if width is None else int(width)
        self.height = scene.size[1] if height is None else int(height)
        self.blob = _Blob()
        self.programs: dict[str, dict[str, str]] = {}
        self.files: dict[str, bytes] = {}     # other files of the page (an sRGB reference as PNG)
        try:
            self.camera = scene.make_camera()
            self.renderer._sync_shadows()   # the maps the page takes as data (the environment is built)
            self.manifest = self._manifest()
        finally:
            self.renderer.release()
        self.manifest["apis"] = APIS[api]
        self.wgsl = {}
        if "webgpu" in APIS[api]:   # every pass but the evaluation's (evaluate_webgpu is its WebGPU twin)
            from .webgpu import translate

            passes = set((self.manifest["evaluate"] or {}).get("passes", []))
            log.info("translating %d programs to WGSL", len(self.programs) - len(passes))
            self.wgsl, interfaces = translate({k: v for k, v in self.programs.items() if k not in passes})
            self.manifest["webgpu"] = {"programs": interfaces}

    # programs ---------------------------------------------------------------------------------
    def _program(self, name: str, vertex: str, fragment: str, *, defines=None, chunks=None) -> str:
        self.programs[name] = {"vertex": assemble(vertex, version=TARGET, defines=defines, chunks=chunks).source,
                               "fragment": assemble(fragment, version=TARGET, defines=defines, chunks=chunks).source}
        return name

    # resources --------------------------------------------------------------------------------
    def _scene_textures(self) -> list[dict]:
        """Everything the scene pass samples besides the G-buffer, in the runtime's binding order."""
        r, out = self.renderer, []
        for g in r.generated:
            for res in g.resources:
                if isinstance(res, TextureResource):
                    out.append(_texture(self.blob, res.name, res))
        for t in self.scene.textures:
            data = np.asarray(Image.open(t.image).convert("RGBA"), np.uint8)[::-1]
            out.append(_texture(self.blob, t.uniform,
                                TextureResource(t.uniform, data, "f1", "linear", wrap="repeat" if t.repeat else "clamp"),
                                generate_mipmaps=bool(t.mipmaps), anisotropy=t.anisotropy if t.mipmaps else 1.0))
        if r.materials is not None:   # a glTF mesh's materials: lib/gltf_material's two textures
            from inshade.runtime.materials import ANISOTROPY

            a = r.materials.arrays
            out.append(_texture(self.blob, "u_material_params",
                                TextureResource("u_material_params", a["u_material_params"], "f4")))
            out.append(_texture(self.blob, "u_material_images",
                                TextureResource("u_material_images", a["u_material_images"], "f2", "linear",
                                                wrap="repeat", array=True),
                                generate_mipmaps=True, anisotropy=ANISOTROPY))
        env = r.environment
        if env is not None:
            s = env.sampler
            arrays = {"u_env_radiance": np.concatenate([s.image, s.texel_probability[..., None]], -1),
                      "u_env_marginal": s.marginal[None, :, None], "u_env_conditional": s.conditional[..., None]}
            for name in ENV_UNIFORMS:
                out.append(_texture(self.blob, name, TextureResource(name, np.asarray(arrays[name], np.float32), "f4")))
        if r.shadow_maps.texture is not None and r.shadow_maps.layers:
            maps = r.shadow_maps.read()[..., None]
            out.append(_texture(self.blob, "u_shadow_map", TextureResource("u_shadow_map", maps, "f4", array=True)))
        return out

    def _blocks(self) -> list[dict]:
        return [{"name": res.name, "data": self.blob.add(bytes(res.data))}
                for g in self.renderer.generated for res in g.resources if isinstance(res, UniformBlockResource)]

    def _static_uniforms(self, live: set[str]) -> dict:
        """The scene pass's uniforms the page does not compute: technique constants, lights, the
        environment's SH, per-frame CPU work, shadow matrices; not the camera's, u_size or a live setting's."""
        r = self.renderer
        camera_names = set(self.camera.uniforms(self.width, self.height)) | {"u_size", "u_sample_index"}
        values = {k: v for k, v in r.uniform_values(self.camera, self.width, self.height).items()
                  if k not in camera_names and k not in live}
        maps = r.shadow_maps
        if "u_shadow_matrix" in r.program:
            slots = r.program["u_shadow_matrix"].array_length
            mats = np.zeros((slots, 4, 4), np.float32)
            if maps.texture is not None and maps.layers:
                mats[: maps.layers] = maps.matrices[: maps.layers].transpose(0, 2, 1)
            values["u_shadow_matrix"] = mats.tobytes()
        if "u_shadow_layers" in r.program:
            values["u_shadow_layers"] = int(maps.layers)
        if r.environment is not None and "u_env_size" in r.program:
            values["u_env_size"] = tuple(float(v) for v in r.environment.size)
        return {k: _uniform_value(v, r.program[k].fmt) for k, v in sorted(values.items())}

    # settings ---------------------------------------------------------------------------------
    def _fingerprint(self, values: dict, own: str) -> str:
        """What the page takes as data at these setting values (all but ``own``'s uniform)."""
        r, spec, scene = self.renderer, self.scene.spec, self.scene
        saved = r.values
        r.values = values
        try:
            parts = [repr(sorted((k, repr(v)) for k, v in r.uniform_values(self.camera, self.width,
                                                                            self.height).items() if k != own))]
            if spec.shadows is not None:
                req = spec.shadows(scene, r.bundles, values)
                parts.append("none" if req is None else repr((req.key, req.size, req.directions.tolist())))
            if spec.frame is not None:
                sh = r.environment_sh() if scene.lit else None
                parts.append(repr(sorted((k, repr(v)) for k, v in spec.frame(FrameInputs(scene, values, sh)).items())))
        finally:
            r.values = saved
        return "|".join(parts)

    def _settings(self) -> tuple[list[dict], set[str]]:
        """The settings as the page's controls: live ones set a uniform; the others are fixed here."""
        r, out, live = self.renderer, [], set()
        for name, s in self.scene.settings.items():
            if not s.exposed or s.binding == "frame":
                continue
            value = r.values[name]
            rec = {"name": name, "label": s.label or name, "type": s.type, "value": value}
            if s.type in ("float", "int"):
                rec.update(min=s.min, max=s.max)
            if s.type == "choice":
                rec["choices"] = list(s.choices)
            if s.binding == "present":   # the present pass's own uniform (the tone mapper): always live
                rec["present"] = s.target
                if s.type == "choice":
                    rec["indices"] = [s.index(c) for c in s.choices]
                out.append(rec)
                continue
            fixed = {"define": "compiled into the program", "codegen": "a code generation option",
                     "environment": "the environment is exported as data"}.get(s.binding)
            if fixed is None:
                base = self._fingerprint(r.values, s.target)
                for alt in _alternatives(s, value):
                    if self._fingerprint({**r.values, name: alt}, s.target) != base:
                        fixed = "the technique's per-frame work is exported as data"
                        break
            if fixed is None:
                rec["uniform"] = s.target
                if s.type == "choice":
                    rec["indices"] = [s.index(c) for c in s.choices]
                live.add(s.target)
            else:
                rec["fixed"] = f"{fixed}: export with --set {name}=VALUE to change it"
            out.append(rec)
        return out, live

    # the page ---------------------------------------------------------------------------------
    def _mesh(self) -> dict | None:
        mesh = self.scene.mesh
        if mesh is None:
            return None
        visibility = self.scene.spec.visibility
        attributes, faces, _ = gbuffer_attributes(mesh.data, visibility)
        names, formats, defines = gbuffer_layout(mesh.data, visibility)
        materials = self.renderer.materials
        peel = self.renderer.blend_layers
        if peel:   # the BLEND layers' passes (runtime/renderer.py _peel)
            for name in ("blend_layer", "blend_resolve"):
                self._program(name, VERTEX, f"passes/gltf_{name}.frag", defines=defines or None)
        return {"program": self._program("gbuffer", MESH_VERTEX, GBUFFER_FRAGMENT, defines=defines or None,
                                         chunks=cutout_chunks(materials is not None
                                                              and (materials.masked or materials.blended))),
                "peel": peel, "layer_reads": [n for n in names if n in BLEND_LAYER_READS],
                "attributes": {n: {"size": int(a.shape[1]), "data": self.blob.add(a)} for n, (a, _) in attributes.items()},
                "indices": None if visibility else self.blob.add(np.ascontiguousarray(faces, np.uint32)),
                "count": int(faces.size), "targets": [{"uniform": f"u_gbuffer_{n}", "format": f}
                                                        for n, f in zip(names, formats)]}

    def _reference(self) -> dict | None:
        """The reference image: an sRGB one as a PNG the browser decodes into an sRGB texture (the
        texture unit decodes to linear before filtering, as the runtime's float copy is decoded
        first); a linear one as half floats (filterable in every WebGL2, 11 significant bits)."""
        ref = self.scene.reference
        if ref is None:
            return None
        if ref.colour == "srgb":
            png = io.BytesIO()
            Image.open(ref.image).convert("RGB").save(png, format="PNG")
            self.files[REFERENCE_PNG] = png.getvalue()
            return {"uniform": "u_reference", "image": REFERENCE_PNG, "filter": "linear", "wrap": "clamp"}
        data = np.ascontiguousarray(self.renderer.reference_image[::-1], np.float16)   # uv (0, 0) = bottom-left
        return _texture(self.blob, "u_reference", TextureResource("u_reference", data, "f2", "linear"))

    def _evaluation(self) -> dict | None:
        """The primary network (or the network SDF) as passes/evaluate.frag and a batch of inputs."""
        r = self.renderer
        bundle = r.bundles[0] if r.bundles else r.sdf_bundle
        if bundle is None:
            return None
        g = generate(bundle, prefix="net", target=TARGET, **r._codegen_options())
        per_pass = WEBGL2["GL_MAX_DRAW_BUFFERS"]   # more output blocks than that: several passes
        passes = [self._program(f"evaluate_{first}", VERTEX, "passes/evaluate.frag", chunks={"network": g.chunk},
                                defines={"EVAL_OUT_FIRST": first,
                                         "EVAL_OUT_TARGETS": min(per_pass, g.out_blocks - first)})
                  for first in range(0, g.out_blocks, per_pass)]
        batch = _batch(bundle, g, self.eval_count)
        textures = [_texture(self.blob, res.name, res) for res in g.resources if isinstance(res, TextureResource)]
        blocks = [{"name": res.name, "data": self.blob.add(bytes(res.data))}
                  for res in g.resources if isinstance(res, UniformBlockResource)]
        return {"bundle": bundle.name, "passes": passes, "blocks_per_pass": per_pass,
                "inputs": self.blob.add(batch), "count": self.eval_count, "in_dim": g.in_dim, "uint_lanes": list(g.uint_lanes),
                "in_blocks": g.in_blocks, "in_uint_blocks": g.in_uint_blocks, "out_dim": g.out_dim,
                "out_blocks": g.out_blocks, "textures": textures, "blocks": blocks}

    def _evaluation_webgpu(self) -> dict | None:
        """The same network and batch as WGSL, for evaluate_webgpu.html (runtime/compute's harness, planned
        against WebGPU's default limits): the code, then each resource at its binding of group 0."""
        from inshade.codegen.glsl import SAMPLER_SUFFIX, StorageBufferResource, resource_bindings
        from inshade.runtime.compute.run import HERE, SOURCES, UINT_HARNESS
        from inshade.runtime.compute.textures import texture_layout, view_dimension

        r = self.renderer
        bundle = r.bundles[0] if r.bundles else r.sdf_bundle
        if bundle is None:
            return None
        options = {k: v for k, v in r._codegen_options().items() if k != "limits"}
        try:
            g = generate(bundle, prefix="net", target="wgsl", **options)
        except (TargetError, LimitError) as exc:   # the WebGL2 page still evaluates it
            return {"unavailable": str(exc)}
        harness = UINT_HARNESS["wgsl"] if g.uint_lanes else SOURCES["wgsl"][0]
        bindings = resource_bindings(g.resources)
        resources = []
        for res in g.resources:
            at = {"binding": bindings[res.name]}
            if isinstance(res, TextureResource):
                resources.append({**_texture(self.blob, res.name, res), **at, "view": view_dimension(res),
                                  "sample_type": texture_layout(res)["texture"]["sample_type"],
                                  "sampler": bindings.get(res.name + SAMPLER_SUFFIX)})
            else:
                kind = "read-only-storage" if isinstance(res, StorageBufferResource) else "uniform"
                resources.append({**at, "name": res.name, "buffer": kind, "data": self.blob.add(bytes(res.data))})
        return {"bundle": bundle.name, "wgsl": g.chunk + "\n" + (HERE / harness).read_text(),
                "inputs": self.blob.add(_batch(bundle, g, self.eval_count)), "count": self.eval_count,
                "in_dim": g.in_dim,
                "uint_lanes": list(g.uint_lanes), "in_blocks": g.in_blocks, "in_uint_blocks": g.in_uint_blocks,
                "out_dim": g.out_dim, "out_blocks": g.out_blocks, "resources": resources}

    def _manifest(self) -> dict:
        r, scene, spec = self.renderer, self.scene, self.scene.spec
        settings, live = self._settings()
        self.programs["scene"] = r.assembled()
        textures = self._scene_textures()
        mesh = self._mesh()
        reference = self._reference()
        evaluation = self._evaluation()
        attachments = spec.attachments
        targets = len(mesh["targets"]) if mesh else 1
        needs = {"GL_MAX_DRAW_BUFFERS": max(attachments, targets)}
        limits = {k: v for k, v in needs.items() if v > WEBGL2[k]}
        all_textures = textures + (evaluation or {}).get("textures", [])
        manifest = {
            "format": FORMAT,
            "name": scene.name, "title": scene.title or scene.name,
            "size": [self.width, self.height],
            "camera": self.camera.to_dict(),
            "exported_from": {"gl_renderer": r.gl.get("renderer"), "program": scene.program,
                              "bundles": [{"name": b.name, "kind": b.kind, "digest": b.digest()} for b in r.bundles]},
            "requires": {"extensions": _extensions(all_textures), "limits": limits},
            "programs": {"scene": "scene", "display": self._program("display", VERTEX, "passes/display.frag",
                                                                    chunks={"display_modes": glsl_chunk()}),
                         "present": self._program("present", VERTEX, "passes/present.frag",
                                                  chunks={"tonemaps": tonemap_chunk()})},
            "attachments": attachments,
            "accumulate": spec.accumulate,
            "textures": textures,
            "blocks": self._blocks(),
            "uniforms": self._static_uniforms(live),
            "settings": settings,
            "mesh": mesh,
            "display": {"mode": scene.display_mode.name.lower(), "split": scene.split,
                        "modes": {m.name.lower(): int(m) for m in scene.display_modes if m in UI_MODES},
                        "reference": reference,
                        "reference_space": scene.reference.space if scene.reference is not None else None,
                        "exposure": 1.0, "error_scale": 4.0,
                        "tonemapped_modes": [int(parse_mode(m)) for m in TONEMAPPED_MODES]},
            "evaluate": evaluation,
            "evaluate_webgpu": self._evaluation_webgpu(),
        }
        if mesh is not None and mesh["peel"]:
            manifest["programs"].update(blend_layer="blend_layer", blend_resolve="blend_resolve")
        if spec.accumulate:
            manifest["programs"]["accumulate"] = self._program("accumulate", VERTEX, "passes/accumulate.frag",
                                                               defines={"ACCUMULATE_ATTACHMENTS": attachments})
        return manifest

    def write(self, folder: Path) -> None:
        """Every file into ``folder`` (which must not exist: ``export_web`` renames it into place)."""
        folder.mkdir(parents=True)
        (folder / "programs").mkdir()
        for name, stages in self.programs.items():
            for stage, source in stages.items():
                (folder / "programs" / f"{name}.{'vert' if stage == 'vertex' else 'frag'}.glsl").write_text(source)
        for name, stages in self.wgsl.items():
            for stage, source in stages.items():
                (folder / "programs" / f"{name}.{'vert' if stage == 'vertex' else 'frag'}.wgsl").write_text(source)
        (folder / DATA).write_bytes(self.blob.bytes())
        for name, data in self.files.items():
            (folder / name).write_bytes(data)
        (folder / MANIFEST).write_text(json.dumps(self.manifest, indent=1, sort_keys=False) + "\n")
        for name in PAGE_FILES:
            shutil.copyfile(PAGE / name, folder / name)


def _batch(bundle, g, count: int = EVAL_BATCH) -> np.ndarray:
    """The evaluation page's inputs [count, in_dim]: each port uniform over the range the parity
    envelope assumes for its semantic (inshade/envelope.py), directions and normals as unit vectors,
    uint lanes ids 0..EVAL_UINT_RANGE - 1; seeded, so every export of an asset has the same batch."""
    from inshade.envelope import input_ranges

    rng = np.random.default_rng(0)
    ranges, _ = input_ranges(bundle)
    batch = np.zeros((count, g.in_dim), np.float32)
    lane = 0
    for port in bundle.inputs:
        cols = slice(lane, lane + port.dim)
        lo, hi = ranges[port.name]
        if port.dtype == "uint":
            batch[:, cols] = rng.integers(0, EVAL_UINT_RANGE, (count, port.dim))
        elif port.semantic in UNIT_SEMANTICS:
            v = rng.normal(size=(count, port.dim))
            batch[:, cols] = v / np.linalg.norm(v, axis=1, keepdims=True)
        else:
            batch[:, cols] = rng.uniform(lo, hi, (count, port.dim))
        lane += port.dim
    return batch


def _alternatives(s, value) -> list:
    """Other values of a setting to probe whether the exported data depends on it."""
    if s.type == "bool":
        return [not value]
    if s.type == "choice":
        return [c for c in s.choices if c != value]
    return [v for v in (s.min, s.max) if v is not None and v != value]


def export_web(source, out, *, force: bool = False, settings: dict | None = None, width: int | None = None,
               height: int | None = None, eval_count: int = EVAL_BATCH, api: str = "webgl2") -> WebExport:
    """Write the page of ``source`` (an asset folder, scene.json or bundle) into the folder ``out``,
    atomically: it appears complete or not at all. An ``out`` that holds files is refused unless
    ``force``; an asset WebGL2 cannot draw raises ``WebLimitError`` naming what it lacks.
    ``eval_count``: the evaluation pages' batch (``inshade bench web`` times larger ones); ``api``: the
    page's programs for WebGL2 (GLSL ES 3.00), WebGPU (WGSL) or both (``auto``: WebGPU where the browser
    has it)."""
    if api not in APIS:
        raise ValueError(f"api: {api!r}: expected one of {', '.join(APIS)}")
    claim_folder(out, force)
    page = WebExport(source, settings=settings, width=width, height=height, eval_count=eval_count, api=api)
    write_folder(out, page.write)
    return page
