"""di_radiance_field: a voxel radiance field (density + SH colour grids) compressed by a multi-head
DI cascade and volume-rendered by ray marching through 3D textures (Differentiable Indirection,
Datta et al. 2023, §4.4 / supp. §1.7).

The field (field.py) is procedural: a soft analytic SDF scene baked into a density grid (sigma) and
a 12-channel colour grid (degree-1 SH logits of a view-dependent colour, colour = sigmoid(sum_k c_k
Y_k(d)): the paper's DVGO with the RGB MLP replaced by PE summation + sigmoid).

A scene draws two networks of kind ``di_radiance_field``, both x [0,1]^3 -> colour (12), density (1):
prefix ``rfg``, the uncompressed grids (two 3D lookup arrays), and prefix ``rfd``, the DI network
(per head a 3D primary, 8-bit, -> a 3D cascaded array, fp32). The ``rfd`` bundle's ``render``
metadata gives the march: ``step`` (dt, box units), ``max_steps``, ``background`` (RGB),
``sigma_scale`` (the density lane is sigma / sigma_scale) and ``density_floor`` (density lanes below it
are empty space, optional, default 0), turned into the chunk <rf_config>. The march: shaders/lib/rf_march.glsl (torch twin march.py); the view setting
switches uncompressed | di | split | error.
"""

from inshade.papers import DIFFERENTIABLE_INDIRECTION
from inshade.technique import Choice, ProgramSpec, Technique, folder_fields, prefixed_bundle

KIND = "di_radiance_field"
PROGRAM = "passes/di_radiance_field.frag"
PREFIX_GRID, PREFIX_DI = "rfg", "rfd"
STOP = 1e-3
# u_rf_view's values in index order (the pass's RF_VIEW_* come from the program's choices)
VIEWS = ("uncompressed", "di", "split", "error")
UNIFORM_DEFAULTS = {"u_rf_view": VIEWS.index("di"), "u_rf_split": 0.5, "u_rf_error_scale": 10.0}
SETTINGS = {
    "view": {"type": "choice", "default": "di", "choices": list(VIEWS), "uniform": "u_rf_view", "label": "view"},
    "split": {"type": "float", "default": 0.5, "min": 0.0, "max": 1.0, "uniform": "u_rf_split",
              "label": "split (uncompressed | DI)"},
    "error_scale": {"type": "float", "default": 10.0, "min": 1.0, "max": 100.0, "uniform": "u_rf_error_scale",
                    "label": "error x"},
    "lut_filter": {"type": "choice", "default": "exact", "choices": ["exact", "fast"], "codegen": "lut_filter",
                   "label": "LUT filtering"},
}


def march_settings(render: dict, where: str) -> tuple[float, int, tuple, float, float]:
    """(step, max_steps, background, sigma_scale, density_floor) from a DI bundle's ``render`` metadata; ValueError naming the field."""
    step, steps, bg = render.get("step"), render.get("max_steps"), render.get("background")
    if isinstance(step, bool) or not isinstance(step, (int, float)) or not 0.0 < step <= 1.0:
        raise ValueError(f"{where}: render.step: must be a number in (0, 1] (the march's dt in box units), "
                         f"got {step!r}")
    if isinstance(steps, bool) or not isinstance(steps, int) or not 1 <= steps <= 4096:
        raise ValueError(f"{where}: render.max_steps: must be an int in 1..4096, got {steps!r}")
    if (not isinstance(bg, (list, tuple)) or len(bg) != 3
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in bg)):
        raise ValueError(f"{where}: render.background: must be [r, g, b] numbers, got {bg!r}")
    scale = render.get("sigma_scale")
    if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not 0.0 < scale < 1e6:
        raise ValueError(f"{where}: render.sigma_scale: must be a number in (0, 1e6) (sigma = density lane x it), "
                         f"got {scale!r}")
    floor = render.get("density_floor", 0.0)
    if isinstance(floor, bool) or not isinstance(floor, (int, float)) or not 0.0 <= floor < 1.0:
        raise ValueError(f"{where}: render.density_floor: must be a number in [0, 1), got {floor!r}")
    return float(step), steps, tuple(float(v) for v in bg), float(scale), float(floor)


def _chunks(scene, bundles, networks, codegen_options) -> dict:
    from inshade.codegen.glsl import flt
    from inshade.codegen.spherical_harmonics import sh_chunks

    b = prefixed_bundle(bundles, networks, PREFIX_DI, PROGRAM, f"a {KIND} bundle")
    step, steps, bg, scale, floor = march_settings(b.meta.get("render") or {}, f"bundle {b.name!r}")
    out = {"rf_config": "\n".join([f"#define RF_STEP {flt(step)}", f"#define RF_MAX_STEPS {steps}",
                                   f"#define RF_STOP {flt(STOP)}", f"#define RF_SIGMA_SCALE {flt(scale)}",
                                   f"#define RF_DENSITY_FLOOR {flt(floor)}",
                                   f"#define RF_BACKGROUND vec3({', '.join(flt(v) for v in bg)})", ""])}
    out.update(sh_chunks(2))
    return out


def _validate(scene):
    """Networks rfg and rfd, each x[3] -> colour[12], density[1]; the DI bundle's march settings."""
    from inshade.bundle import load

    for prefix in (PREFIX_GRID, PREFIX_DI):
        nets = [n for n in scene.networks if n.prefix == prefix]
        if len(nets) != 1:
            raise ValueError(f"networks: a {KIND} scene needs one network with prefix \"{prefix}\" "
                             f"({'the uncompressed grids' if prefix == PREFIX_GRID else 'the DI network'})")
        bundle = load(nets[0].bundle)
        where = f"bundle {bundle.name!r}"
        ins = [(p.name, p.dim) for p in bundle.inputs]
        outs = [(p.name, p.dim) for p in bundle.outputs]
        if ins != [("x", 3)] or outs != [("colour", 12), ("density", 1)]:
            raise ValueError(f"{where}: the march feeds x[3] and reads colour[12], density[1]; the bundle has "
                             f"inputs {', '.join(f'{n}[{d}]' for n, d in ins)} and outputs "
                             f"{', '.join(f'{n}[{d}]' for n, d in outs)}")
        if prefix == PREFIX_DI:
            march_settings(bundle.meta.get("render") or {}, where)


TECHNIQUE = Technique(
    name="di_radiance_field",
    summary="a voxel radiance field compressed by DI cascades, ray marched in the shader",
    paper=DIFFERENTIABLE_INDIRECTION,
    kinds=(KIND,),
    programs=(ProgramSpec(PROGRAM, geometry="fullscreen", bundle_kinds=(KIND,), uniforms=UNIFORM_DEFAULTS,
                          chunks=_chunks, validate=_validate, choices=(Choice("u_rf_view", "RF_VIEW", VIEWS),)),),
    **folder_fields(
        __name__,
        train="bake a procedural radiance field (density + SH colour grids) and compress it with "
              "multi-head DI cascades",
        bench="DI vs uncompressed grids per compression ratio: PSNR, FLIP, MB per field, frame time",
        shaders=True),
)
