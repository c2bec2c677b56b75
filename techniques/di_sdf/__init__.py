"""di_sdf: an SDF as a DI lookup-array cascade (3D primary -> cascaded array), traced by the sdf
technique's pass like any network SDF."""
from inshade.papers import DIFFERENTIABLE_INDIRECTION
from inshade.technique import Technique, folder_fields

TECHNIQUE = Technique(
    name="di_sdf",
    summary="an SDF as a DI lookup-array cascade, against an MLP SDF of equal bytes",
    paper=DIFFERENTIABLE_INDIRECTION,
    kinds=("di_sdf",),
    **folder_fields(
        __name__,
        train="fit a DI lookup-array cascade SDF to a watertight mesh",
        bench="DI-SDF vs MLP SDF at equal bytes: surface error, IoU, speed"),
)
