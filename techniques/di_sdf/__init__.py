"""di_sdf: an SDF as a DI lookup-array cascade (3D primary -> cascaded array), traced by the sdf
technique's pass like any network SDF."""
from inshade.papers import DIFFERENTIABLE_INDIRECTION
from inshade.technique import folder_technique

TECHNIQUE = folder_technique(
    __name__, "an SDF as a DI lookup-array cascade, against an MLP SDF of equal bytes", DIFFERENTIABLE_INDIRECTION,
    train="fit a DI lookup-array cascade SDF to a watertight mesh",
    bench="DI-SDF vs MLP SDF at equal bytes: surface error, IoU, speed")
