"""di_texture: Differentiable Indirection texture compression (a primary 2D lookup array pointing
into a cascaded one), decoded per pixel by the generated GLSL; drawn as a 2D field."""
from inshade.papers import DIFFERENTIABLE_INDIRECTION
from inshade.technique import Technique

TECHNIQUE = Technique(
    name="di_texture",
    summary="DI texture compression (image -> lookup-array cascade), against ASTC / BC1 / BC7",
    paper=DIFFERENTIABLE_INDIRECTION,
    kinds=("di_texture",),
    train="inshade.techniques.di_texture.train",
    train_help="compress an image into a DI texture asset (IMAGE or skimage:NAME)",
    train_alias="compress",
    bench="inshade.techniques.di_texture.bench",
    bench_help="DI texture compression vs ASTC / BC1 / BC7: PSNR, FLIP, bits per pixel",
)
