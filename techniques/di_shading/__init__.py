"""di_shading: the DI footprint sampler trained end to end through the frozen DI Disney decoder
(a shaded loss blended with the sampler's proxy loss by lambda), on the PBR bricks set on a plane seen
at grazing angles, next to the independently trained sampler and the appearance-filtered reference."""

from inshade.papers import DIFFERENTIABLE_INDIRECTION
from inshade.technique import Choice, ProgramSpec, folder_technique

# SHADING_VIEW: the pass's views and their indices (its SHADING_* come from the program's choices)
VIEWS = {"end_to_end": 0, "independent": 1, "reference": 2, "split": 3, "trilinear": 4, "analytic": 5}

TECHNIQUE = folder_technique(
    __name__, "DI footprint sampler + DI Disney decoder optimised end to end", DIFFERENTIABLE_INDIRECTION,
    kinds=("di_shading", "di_shading_brdf"),
    programs=(ProgramSpec("passes/shading_plane.frag", geometry="fullscreen", attachments=4,
                          choices=(Choice("SHADING_VIEW", "SHADING", VIEWS),)),),
    train="DI footprint sampler trained end to end through the frozen DI Disney decoder (lambda sweep)",
    bench="end-to-end vs independent DI sampler + decoder: PSNR / FLIP vs the 16-sample reference, frame time")
