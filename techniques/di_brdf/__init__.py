"""di_brdf: DI approximations of the GGX and Disney BRDFs, shown on material-ball grids next to the
analytic BRDFs."""
from pathlib import Path

from inshade.papers import DIFFERENTIABLE_INDIRECTION
from inshade.technique import ProgramSpec, Technique

TECHNIQUE = Technique(
    name="di_brdf",
    summary="DI GGX and Disney BRDFs on material balls, against the analytic BRDFs",
    paper=DIFFERENTIABLE_INDIRECTION,
    kinds=("di_brdf_ggx", "di_brdf_disney"),
    old_kinds={"di_ggx": "di_brdf_ggx", "di_disney": "di_brdf_disney"},
    programs=(ProgramSpec("passes/material_balls.frag", geometry="fullscreen"),),
    train="inshade.techniques.di_brdf.train",
    train_help="DI approximations of the GGX and Disney BRDFs",
    bench="inshade.techniques.di_brdf.bench",
    bench_help="learned (DI) vs analytic GGX / Disney BRDF shader speed, 1-4 lights",
    shaders=Path(__file__).resolve().parent / "shaders",
)
