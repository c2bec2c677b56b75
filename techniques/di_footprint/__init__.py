"""di_footprint: the DI footprint-aware texture sampler (no mip chain) on a receding plane, against
GL trilinear and anisotropic filtering."""

from inshade.papers import DIFFERENTIABLE_INDIRECTION
from inshade.technique import Choice, ProgramSpec, folder_technique

# FOOTPRINT_MODE: the pass's samplers and their indices (its FOOTPRINT_* come from the program's choices)
MODES = {"di": 0, "trilinear": 1, "anisotropic": 2, "bilinear": 3, "explicit_lod": 4}

TECHNIQUE = folder_technique(
    __name__, "DI footprint-aware texture sampler vs GL trilinear / anisotropic", DIFFERENTIABLE_INDIRECTION,
    programs=(ProgramSpec("passes/footprint_plane.frag", geometry="fullscreen", attachments=2,
                          choices=(Choice("FOOTPRINT_MODE", "FOOTPRINT", MODES),)),),
    train="DI footprint-aware texture sampler (no mip chain)",
    bench="DI footprint-aware sampler vs GL trilinear / anisotropic")
