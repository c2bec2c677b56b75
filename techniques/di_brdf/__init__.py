"""di_brdf: DI approximations of the GGX and Disney BRDFs, shown on material-ball grids next to the
analytic BRDFs."""

from inshade.papers import DIFFERENTIABLE_INDIRECTION
from inshade.technique import Choice, ProgramSpec, Technique, folder_fields

# BRDF_VIEW and BRDF_MODEL of the material-ball pass, with their indices (its BRDF_VIEW_* and
# BRDF_MODEL_* come from the program's choices)
VIEWS = {"analytic": 0, "learned": 1, "split": 2, "diffuse": 3}
MODELS = {"ggx": 1, "disney": 2}

TECHNIQUE = Technique(
    name="di_brdf",
    summary="DI GGX and Disney BRDFs on material balls, against the analytic BRDFs",
    paper=DIFFERENTIABLE_INDIRECTION,
    kinds=("di_brdf_ggx", "di_brdf_disney"),
    old_kinds={"di_ggx": "di_brdf_ggx", "di_disney": "di_brdf_disney"},
    programs=(ProgramSpec("passes/material_balls.frag", geometry="fullscreen",
                          choices=(Choice("BRDF_VIEW", "BRDF_VIEW", VIEWS),
                                   Choice("BRDF_MODEL", "BRDF_MODEL", MODELS))),),
    **folder_fields(
        __name__,
        train="DI approximations of the GGX and Disney BRDFs",
        bench="learned (DI) vs analytic GGX / Disney BRDF shader speed, 1-4 lights",
        shaders=True),
)
