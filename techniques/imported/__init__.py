"""imported: your own network, brought in with ``inshade.export`` (a torch module) or ``inshade
convert`` (an ONNX file), and drawn by what it is (``as_=`` / ``--as``; inshade/convert/shown_as.py):
an image by the shared 2D field pass, an SDF by the shared sphere tracer, and a radiance field
(x, direction -> rgb, density) by this folder's pass, passes/imported_field.frag, through the shared
volume march (shaders/lib/field_march.glsl, torch twin march.py).

A field bundle's ``render.field`` gives the march (codegen/field.py, turned into the chunk
<field_config>). The network: inputs 6 lanes (position, direction, in one or two ports), outputs 4
lanes (rgb, density; one or two ports).
"""

from inshade.codegen.field import field_chunks, field_settings
from inshade.technique import ProgramSpec, Technique, folder_fields

KIND = "imported"
PROGRAM = "passes/imported_field.frag"


def _chunks(scene, bundles, networks, codegen_options) -> dict:
    return field_chunks(bundles[0])


def _validate(scene):
    from inshade.bundle import load

    if len(scene.networks) != 1:
        raise ValueError(f"networks: {PROGRAM} draws one field network")
    field_settings(load(scene.networks[0].bundle))


TECHNIQUE = Technique(
    name="imported",
    summary="your own network (inshade.export / inshade convert), drawn as an image, an SDF or a radiance field",
    kinds=(KIND,),
    programs=(ProgramSpec(PROGRAM, geometry="fullscreen", chunks=_chunks, validate=_validate),),
    **folder_fields(__name__, shaders=True),
)
