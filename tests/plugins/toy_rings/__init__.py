"""toy_rings: a technique defined entirely in this folder (tests/test_techniques.py registers it
through INSHADE_TECHNIQUES). It draws a 2 -> 3 sine network over the uv plane, tinted by a colour
the CPU computes each frame from a scene setting, with a palette chunk generated from Python:
every hook a ProgramSpec has, and a bench `inshade bench suite` runs from its SUITE entry
(tests/bench/test_bench_suite.py), with no edit outside this folder."""
from pathlib import Path

from inshade.technique import Paper, ProgramSpec, Technique

PALETTE = (0.25, 0.5, 1.0)


def palette_chunk(scene, bundles, networks, codegen_options):
    return {"toy_palette": "const vec3 TOY_PALETTE = vec3(%.9g, %.9g, %.9g);\n" % PALETTE}


def tint(inputs):
    """The per-frame CPU work: a tint from the 'warmth' setting."""
    w = float(inputs.values["warmth"])
    return {"u_toy_tint": (1.0, 1.0 - 0.5 * w, 1.0 - w)}


def check(scene):
    if "warmth" not in scene.settings:
        raise ValueError("settings.warmth: toy_rings needs a 'warmth' setting")


TECHNIQUE = Technique(
    name="toy_rings",
    summary="a test-only technique: sine rings over uv, tinted per frame",
    paper=Paper("Sine rings, a toy", "inshade tests"),
    kinds=("toy_rings",),
    programs=(ProgramSpec("passes/toy_rings.frag", geometry="fullscreen", uniforms={"u_toy_tint": (1.0, 1.0, 1.0)},
                          chunks=palette_chunk, frame=tint, validate=check),),
    train="toy_rings.train",
    train_help="write the toy_rings asset (a random 2 -> 3 sine network)",
    train_alias="rings",
    bench="toy_rings.bench",
    bench_help="time the toy network in numpy",
    shaders=Path(__file__).resolve().parent / "shaders",
)
