"""di_pbr_set: an 8-lane PBR texture set (albedo, normal, roughness, AO) compressed by one DI
cascade and shaded on a lit, uv-mapped mesh; its bundles are DI texture bundles with 8 lanes."""
from pathlib import Path

from inshade.papers import DIFFERENTIABLE_INDIRECTION
from inshade.technique import Choice, ProgramSpec, Technique

# u_pbr_view's values in index order (the pass's PBR_VIEW_* come from the program's choices)
VIEWS = ("uncompressed", "di", "split")

TECHNIQUE = Technique(
    name="di_pbr_set",
    summary="a DI-compressed PBR texture set on a lit, uv-mapped mesh",
    paper=DIFFERENTIABLE_INDIRECTION,
    programs=(ProgramSpec("passes/mesh_pbr_set.frag", geometry="mesh", mesh_attributes=("uv", "tangent"),
                          choices=(Choice("u_pbr_view", "PBR_VIEW", VIEWS),)),),
    train="inshade.techniques.di_pbr_set.train",
    train_help="a DI-compressed PBR texture set (8 lanes) on a lit mesh",
    shaders=Path(__file__).resolve().parent / "shaders",
)
