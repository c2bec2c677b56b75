"""imported: your own network, brought in with ``inshade.export`` (a torch module) or ``inshade
convert`` (an ONNX file), and drawn by what it is (``as_=`` / ``--as``; inshade/convert/shown_as.py):
an image by the shared 2D field pass, an SDF by the shared sphere tracer, and a radiance field
(x, direction -> rgb, density) by this folder's volume march, passes/imported_field.frag
(shaders/lib/imported_field.glsl, torch twin march.py).

A field bundle's ``render.field`` gives the march: ``box`` [[x, y, z], [x, y, z]] (world bounds the
network is marched through), ``step`` (dt, world units), ``max_steps``, ``background`` [r, g, b];
turned into the chunk <imported_field_config>. The network: inputs 6 lanes (position, direction,
in one or two ports), outputs 4 lanes (rgb, density; one or two ports).
"""

from inshade.technique import ProgramSpec, Technique, folder_fields

KIND = "imported"
PROGRAM = "passes/imported_field.frag"
STOP = 1e-3      # the march stops once transmittance falls below this


def _number(v, lo, hi, where, what):
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not lo < v <= hi:
        raise ValueError(f"{where}: render.field.{what}: must be a number in ({lo:g}, {hi:g}], got {v!r}")
    return float(v)


def field_settings(bundle) -> dict:
    """The march of a field bundle's ``render.field``, checked; ValueError naming the field."""
    where = f"bundle {bundle.name!r}"
    if bundle.in_dim != 6 or bundle.out_dim != 4:
        raise ValueError(f"{where}: a field maps position + direction (6 lanes) to rgb + density (4 lanes); it has "
                         f"{bundle.in_dim} -> {bundle.out_dim}")
    spec = (bundle.meta.get("render") or {}).get("field")
    if not isinstance(spec, dict):
        raise ValueError(f"{where}: render.field: missing ({{box, step, max_steps, background}})")
    box = spec.get("box")
    if (not isinstance(box, list) or len(box) != 2 or not all(isinstance(c, list) and len(c) == 3 for c in box)
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for c in box for v in c)
            or not all(a < b for a, b in zip(*box))):
        raise ValueError(f"{where}: render.field.box: must be [[x0, y0, z0], [x1, y1, z1]] with x0 < x1 ..., got {box!r}")
    bg = spec.get("background", [0.0, 0.0, 0.0])
    if not isinstance(bg, list) or len(bg) != 3 or not all(isinstance(v, (int, float)) for v in bg):
        raise ValueError(f"{where}: render.field.background: must be [r, g, b], got {bg!r}")
    steps = spec.get("max_steps")
    if isinstance(steps, bool) or not isinstance(steps, int) or not 1 <= steps <= 4096:
        raise ValueError(f"{where}: render.field.max_steps: must be an int in 1..4096, got {steps!r}")
    return {"box": [[float(v) for v in c] for c in box], "step": _number(spec.get("step"), 0.0, 1e6, where, "step"),
            "max_steps": steps, "background": [float(v) for v in bg]}


def _chunks(scene, bundles, networks, codegen_options) -> dict:
    from inshade.codegen.glsl import flt

    s = field_settings(bundles[0])
    vec3 = lambda v: f"vec3({', '.join(flt(x) for x in v)})"  # noqa: E731
    return {"imported_field_config": "\n".join([
        f"#define FIELD_BOX_LO {vec3(s['box'][0])}", f"#define FIELD_BOX_HI {vec3(s['box'][1])}",
        f"#define FIELD_STEP {flt(s['step'])}", f"#define FIELD_MAX_STEPS {s['max_steps']}",
        f"#define FIELD_STOP {flt(STOP)}", f"#define FIELD_BACKGROUND {vec3(s['background'])}", ""])}


def _validate(scene):
    from inshade.bundle import load

    if len(scene.networks) != 1:
        raise ValueError(f"networks: {PROGRAM} draws one field network")
    field_settings(load(scene.networks[0].bundle))


TECHNIQUE = Technique(
    name="imported",
    summary="your own network (inshade.export / inshade convert), drawn as an image, an SDF or a radiance field",
    kinds=(KIND,),
    programs=(ProgramSpec(PROGRAM, geometry="fullscreen", chunks=_chunks, validate=_validate),),
    **folder_fields(__name__, shaders=True),
)
