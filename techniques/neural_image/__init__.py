"""neural_image: an image as a coordinate network (a multiresolution lookup-array encoding, or a
frequency or SIREN encoding, + MLP), drawn as a field over the camera's uv plane."""
from inshade.technique import ProgramSpec, Technique, folder_fields

TECHNIQUE = Technique(
    name="neural_image",
    summary="an image fitted by a coordinate MLP, drawn as a 2D field",
    kinds=("neural_image",),
    # passes/field2d.frag (shared library) draws any bundle uv -> colour: DI textures use it too.
    programs=(ProgramSpec("passes/field2d.frag", geometry="fullscreen", field_inputs=2),),
    **folder_fields(__name__, train="fit a neural image to a skimage.data photo"),
)
