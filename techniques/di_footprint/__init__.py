"""di_footprint: the DI footprint-aware texture sampler (no mip chain) on a receding plane, against
GL trilinear and anisotropic filtering."""

from inshade.papers import DIFFERENTIABLE_INDIRECTION
from inshade.technique import Choice, ProgramSpec, Technique, folder_fields

# FOOTPRINT_MODE: the pass's samplers and their indices (its FOOTPRINT_* come from the program's choices)
MODES = {"di": 0, "trilinear": 1, "anisotropic": 2, "bilinear": 3, "explicit_lod": 4}

TECHNIQUE = Technique(
    name="di_footprint",
    summary="DI footprint-aware texture sampler vs GL trilinear / anisotropic",
    paper=DIFFERENTIABLE_INDIRECTION,
    kinds=("di_footprint",),
    programs=(ProgramSpec("passes/footprint_plane.frag", geometry="fullscreen", attachments=2,
                          choices=(Choice("FOOTPRINT_MODE", "FOOTPRINT", MODES),)),),
    **folder_fields(
        __name__,
        train="DI footprint-aware texture sampler (no mip chain)",
        bench="DI footprint-aware sampler vs GL trilinear / anisotropic",
        shaders=True),
)
