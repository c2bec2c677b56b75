"""di_texture: Differentiable Indirection texture compression (a primary 2D lookup array pointing
into a cascaded one), decoded per pixel by the generated GLSL; drawn as a 2D field."""
from inshade.papers import DIFFERENTIABLE_INDIRECTION
from inshade.technique import folder_technique

TECHNIQUE = folder_technique(
    __name__, "DI texture compression (image -> lookup-array cascade), against ASTC / BC1 / BC7",
    DIFFERENTIABLE_INDIRECTION, train_alias="compress",
    train="compress an image into a DI texture asset (IMAGE or skimage:NAME)",
    bench="DI texture compression vs ASTC / BC1 / BC7: PSNR, FLIP, bits per pixel")
