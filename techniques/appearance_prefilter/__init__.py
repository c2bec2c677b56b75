"""appearance_prefilter: Deep Appearance Prefiltering (Bako et al. 2022): a scene
voxelised at several scales, one latent per voxel (an auto-decoder: learned embeddings in place of
the paper's CNN encoders) and residual MLP decoders for coverage, albedo, phase and phase slice;
a full-screen pass marches each pixel's beam through the scale its footprint asks for.

The bundle (kind ``appearance_prefilter``, network prefix ``dap``): inputs slot (uint), view (3),
light (3); first node ``sparse_voxels`` (the latents, cells, spheres and the cell index); outputs
coverage (M*M), albedo (3), phase (1), slice (B). Its ``render`` metadata holds ``mask`` (M) and
``bins`` (B), optionally ``bins_theta`` / ``bins_phi`` (BT x BP = B; default BP = 2 BT), which
this record turns into the chunk <dap_config>. The march: shaders/lib/dap_march.glsl (torch twin
march.py).

A glTF file's asset (``--scene FILE.glb``, user_scene.py) is drawn by a second program,
passes/appearance_prefilter_gltf.frag: the file as the scene's mesh with its reference shading
(lib/gltf_material) beside the prefiltered voxels, its views ``GLTF_VIEWS``; its bundle's ``render``
also holds ``world`` ({"centre": [3], "scale": s}: box = (world - centre) * scale + 0.5), which
becomes DAP_WORLD_CENTRE / DAP_WORLD_SCALE in <dap_config>.
"""

from inshade.papers import APPEARANCE_PREFILTERING
from inshade.technique import Choice, ProgramSpec, Technique, folder_fields, prefixed_bundle

KIND = "appearance_prefilter"
PREFIX = "dap"
PROGRAM = "passes/appearance_prefilter.frag"
GLTF_PROGRAM = "passes/appearance_prefilter_gltf.frag"
# u_dap_view's values in index order (the pass's DAP_VIEW_* come from the program's choices)
VIEWS = ("prefiltered", "scale", "coverage", "albedo")
# the glTF pass's: the same, then the file's reference shading and the two side by side
GLTF_VIEWS = VIEWS + ("reference", "split")
UNIFORM_DEFAULTS = {"u_dap_distance": 1.0, "u_dap_force_scale": -1, "u_dap_view": VIEWS.index("prefiltered"),
                    "u_dap_shadows": 0}
# scene.json "settings" of an asset: the viewer's distance slider (`--set distance=...`), the debug
# views, a forced scale and the sun's shadow map
SETTINGS = {
    "distance": {"type": "float", "default": 1.0, "min": 0.25, "max": 16.0, "uniform": "u_dap_distance",
                 "label": "distance (x the camera's)"},
    "view": {"type": "choice", "default": VIEWS[0], "choices": list(VIEWS), "uniform": "u_dap_view", "label": "view"},
    "force_scale": {"type": "int", "default": -1, "min": -1, "max": 12, "uniform": "u_dap_force_scale",
                    "label": "scale (-1: by footprint)"},
    "shadows": {"type": "bool", "default": True, "uniform": "u_dap_shadows", "label": "sun shadows"},
}
SHADOW_SIZE = 512   # texels per side of the sun's shadow map


def bins_layout(render: dict, where: str) -> tuple[int, int, int, int]:
    """(M, B, BT, BP) from a bundle's ``render`` metadata; ValueError naming the field."""
    def count(key):
        v = render.get(key)
        if isinstance(v, bool) or not isinstance(v, int) or v < 1:
            raise ValueError(f"{where}: render.{key}: must be an int >= 1 (the appearance_prefilter "
                             f"{'mask side M' if key == 'mask' else 'phase bins'}), got {v!r}")
        return v
    m, b = count("mask"), count("bins")
    if "bins_theta" in render or "bins_phi" in render:
        bt, bp = count("bins_theta"), count("bins_phi")
    else:   # the presets' layout: BP = 2 BT, so B = 2 BT^2
        bt = round((b / 2) ** 0.5)
        bp = 2 * bt
    if bt * bp != b:
        raise ValueError(f"{where}: render.bins: {b} is not bins_theta x bins_phi ({bt} x {bp}); "
                         "give render.bins_theta and render.bins_phi")
    return m, b, bt, bp


def _dap_bundle(scene, bundles, networks):
    return prefixed_bundle(bundles, networks, PREFIX, PROGRAM, f"the {KIND} bundle")


def _chunks(scene, bundles, networks, codegen_options) -> dict:
    """<dap_config> from the bundle's render metadata, and the SH basis when the runtime does not
    add it (a full-screen scene is not ``lit``)."""
    bundle = _dap_bundle(scene, bundles, networks)
    m, b, bt, bp = bins_layout(bundle.meta.get("render") or {}, f"bundle {bundle.name!r}")
    out = {"dap_config": "\n".join([f"#define DAP_MASK {m}", f"#define DAP_BINS {b}",
                                    f"#define DAP_BINS_THETA {bt}", f"#define DAP_BINS_PHI {bp}", ""])}
    if not scene.lit:
        from inshade.codegen.spherical_harmonics import sh_chunks

        out.update(sh_chunks(int(_environment(scene)["degree"])))
    return out


def _gltf_chunks(scene, bundles, networks, codegen_options) -> dict:
    """_chunks, plus DAP_WORLD_CENTRE / DAP_WORLD_SCALE from the bundle's render.world."""
    out = _chunks(scene, bundles, networks, codegen_options)
    bundle = _dap_bundle(scene, bundles, networks)
    world = (bundle.meta.get("render") or {}).get("world")
    try:
        centre = [float(c) for c in world["centre"]]
        scale = float(world["scale"])
        if len(centre) != 3 or not scale > 0.0:
            raise ValueError
    except (TypeError, KeyError, ValueError):
        raise ValueError(f"bundle {bundle.name!r}: render.world: {GLTF_PROGRAM} needs {{\"centre\": [x, y, z], "
                         f"\"scale\": s > 0}} (the file's map into the voxels' unit box), got {world!r}") from None
    out["dap_config"] += (f"#define DAP_WORLD_CENTRE vec3({centre[0]:.9g}, {centre[1]:.9g}, {centre[2]:.9g})\n"
                          f"#define DAP_WORLD_SCALE {scale:.9g}\n")
    return out


def _environment(scene) -> dict:
    """scene.environment with the defaults the runtime fills in for lit scenes only."""
    return {"sky": "overcast", "rotation": 0.0, "degree": 4, **(scene.environment or {})}


def environment_sh(scene, values):
    """The radiance SH [K, 3] float32 of the scene's environment under the current settings (the
    renderer computes it only for lit scenes: SDF or mesh)."""
    import math

    import numpy as np

    env = _environment(scene)
    for name, s in scene.settings.items():
        if s.binding == "environment":
            env[s.target] = values[name]
    if env["sky"] == "map":
        from inshade.sh import rotate_sh, rotation_matrix

        coeffs = scene.environment_map
        if float(env["rotation"]):
            coeffs = rotate_sh(coeffs, rotation_matrix([0.0, 1.0, 0.0], math.radians(float(env["rotation"]))))
        return np.asarray(coeffs, np.float32)
    from inshade.codegen.sdf import environment_sh as sky_sh

    return sky_sh(env["sky"], float(env["rotation"]), int(env["degree"]))


def sun(scene):
    """The scene's first directional light (the march's sun), or None."""
    return next((light for light in scene.lights if light.kind == "directional"), None)


_CASTERS: dict = {}   # (bundle name, cells digest) -> (vertices, faces): one mesh per bundle, built once


def _shadows(scene, bundles, values):
    """The sun's shadow map, cast by the finest scale's occupied cells as cubes (grid.py), while a
    setting bound to u_dap_shadows is on; None (no map) otherwise."""
    import hashlib

    import numpy as np

    from inshade.technique import ShadowRequest

    from .grid import caster_cubes

    on = any(values.get(name) for name, s in scene.settings.items()
             if s.binding == "uniform" and s.target == "u_dap_shadows")
    light = sun(scene)
    if not on or light is None:
        return None
    bundle = _dap_bundle(scene, bundles, scene.networks)
    node = next(n for n in bundle.nodes if n.type == "sparse_voxels")
    cells = bundle.tensor(node, "cells")
    key = (bundle.name, hashlib.sha1(np.ascontiguousarray(cells).tobytes()).hexdigest())
    if key not in _CASTERS:
        _CASTERS.clear()
        _CASTERS[key] = caster_cubes(cells, int(node.params["scale_max"]))
    vertices, faces = _CASTERS[key]
    return ShadowRequest(vertices, faces, np.asarray([light.direction], np.float32), SHADOW_SIZE, key)


def _frame(inputs) -> dict:
    sh = inputs.environment_sh
    if sh is None:
        sh = environment_sh(inputs.scene, inputs.values)
    return {"u_sh": sh.tobytes()}


def _validate(scene):
    """One network at prefix "dap" whose render metadata says M and B and whose ports are the
    march's; an SH environment."""
    from inshade.bundle import load

    nets = [n for n in scene.networks if n.prefix == PREFIX]
    if len(nets) != 1:
        raise ValueError(f"networks: an {KIND} scene needs one network with prefix \"{PREFIX}\" (the {KIND} bundle)")
    bundle = load(nets[0].bundle)
    where = f"bundle {bundle.name!r}"
    m, b, _, _ = bins_layout(bundle.meta.get("render") or {}, where)
    ins = [(p.name, p.dim, p.dtype) for p in bundle.inputs]
    if ins != [("slot", 1, "uint"), ("view", 3, "float"), ("light", 3, "float")]:
        raise ValueError(f"{where}: inputs: the march feeds slot[1] uint, view[3], light[3]; the bundle has "
                         + ", ".join(f"{n}[{d}] {t}" for n, d, t in ins))
    outs = [(p.name, p.dim) for p in bundle.outputs]
    if outs != [("coverage", m * m), ("albedo", 3), ("phase", 1), ("slice", b)]:
        raise ValueError(f"{where}: outputs: the march reads coverage[{m * m}], albedo[3], phase[1], slice[{b}] "
                         f"(M = {m}, B = {b} from render); the bundle has "
                         + ", ".join(f"{n}[{d}]" for n, d in outs))
    if scene.environment is None:
        raise ValueError(f"environment: {PROGRAM} lights the voxels with an SH environment: "
                         "add {\"sky\": ..., \"degree\": N}")
    if not scene.lit:   # the runtime parses the environment of SDF and mesh scenes only
        from inshade.sh import MAX_DEGREE, SKY_PRESETS

        env = _environment(scene)
        extra = sorted(set(env) - {"sky", "rotation", "degree"})
        if extra:
            raise ValueError(f"environment.{extra[0]}: unknown field here (known: degree, rotation, sky)")
        if env["sky"] not in SKY_PRESETS:
            raise ValueError(f"environment.sky: unknown sky {env['sky']!r} (known: {', '.join(SKY_PRESETS)})")
        if env["degree"] not in range(1, MAX_DEGREE + 1):
            raise ValueError(f"environment.degree: must be an int in 1..{MAX_DEGREE}, got {env['degree']!r}")


TECHNIQUE = Technique(
    name="appearance_prefilter",
    summary="Deep Appearance Prefiltering: multi-scale voxel latents + coverage/albedo/phase decoders, "
            "marched per pixel at the footprint's scale",
    paper=APPEARANCE_PREFILTERING,
    kinds=(KIND,),
    programs=(ProgramSpec(PROGRAM, geometry="fullscreen", bundle_kinds=(KIND,), uniforms=UNIFORM_DEFAULTS,
                          chunks=_chunks, frame=_frame, validate=_validate, shadows=_shadows,
                          choices=(Choice("u_dap_view", "DAP_VIEW", VIEWS),)),
              ProgramSpec(GLTF_PROGRAM, geometry="mesh", mesh_attributes=("materials",), bundle_kinds=(KIND,),
                          uniforms=UNIFORM_DEFAULTS, chunks=_gltf_chunks, frame=_frame, validate=_validate,
                          shadows=_shadows, choices=(Choice("u_dap_view", "DAP_VIEW", GLTF_VIEWS),))),
    **folder_fields(
        __name__,
        train="voxelise a procedural scene or a glTF / OBJ file at several scales, bake per-voxel "
              "coverage/albedo/phase, fit voxel latents + decoders",
        bench="prefiltered voxels vs supersampled and 1-spp full geometry and a decimated mesh: quality, "
              "memory, speed",
        shaders=True),
)
