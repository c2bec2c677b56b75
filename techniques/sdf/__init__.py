"""sdf: analytic SDF scenes (geometry/sdf.py: primitives, smooth booleans, repetition) sphere-traced
and lit by the SH environment. Network SDFs (neural_sdf, di_sdf) are traced by the same pass."""
from inshade.technique import ProgramSpec, Technique

TECHNIQUE = Technique(
    name="sdf",
    summary="analytic and network SDF scenes, sphere-traced, SH diffuse lighting",
    programs=(ProgramSpec("passes/sdf_diffuse.frag", geometry="sdf"),),
)
