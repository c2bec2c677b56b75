"""hash_grid: instant-NGP's multiresolution hash encoding + a small MLP (Müller et al. 2022), one
trainer for several applications (train.py APPS): an image drawn by the shared 2D field pass, a
mesh's signed distance traced by the sdf technique's pass, and a radiance field ray marched with an
occupancy grid by its own pass (radiance_field_render.py)."""

from inshade.technique import Paper, Technique, folder_fields

from .radiance_field_render import KIND as RADIANCE_FIELD_KIND, PROGRAM_SPEC as RADIANCE_FIELD_PROGRAM

INSTANT_NGP = Paper("Instant Neural Graphics Primitives with a Multiresolution Hash Encoding",
                    "ACM Transactions on Graphics (SIGGRAPH) 2022", arxiv="2201.05989", doi="10.1145/3528223.3530127")

TECHNIQUE = Technique(
    name="hash_grid",
    summary="instant-NGP hash encoding + MLP: a 2K image, a mesh SDF, a radiance field",
    paper=INSTANT_NGP,
    kinds=("hash_grid_image", "hash_grid_sdf", RADIANCE_FIELD_KIND),
    # The image is drawn by passes/field2d.frag (neural_image's), the SDF by passes/sdf_diffuse.frag
    # (sdf's) through the network-SDF contract; the radiance field by its own march.
    programs=(RADIANCE_FIELD_PROGRAM,),
    **folder_fields(
        __name__,
        train="fit a hash grid + MLP: APP image (2048^2 photo collage), sdf (a mesh) or radiance_field "
              "(a procedural scene from its views)",
        bench="hash grid + MLP image, SDF and radiance field vs the MLP-only network and a DI cascade at equal "
              "bytes: quality, bytes, FLOPs and fetches per pixel, frame time",
        shaders=True),
    # instant-ngp NeRF snapshots become radiance-field assets (inshade convert FILE -o FOLDER)
    converts={".msgpack": "inshade.techniques.hash_grid.ngp_snapshot", ".ingp": "inshade.techniques.hash_grid.ngp_snapshot"},
)
