"""Built-in techniques: one folder each, registered by one line in ``BUILTIN``.

Each folder's ``__init__`` defines ``TECHNIQUE`` (inshade/technique.py) and imports nothing heavy;
its trainer, bench, twin and GLSL sit beside it.
"""

BUILTIN = (
    "neural_image",
    "sdf",
    "neural_sdf",
    "prt",
    "di_texture",
    "di_pbr_set",
    "di_footprint",
    "di_brdf",
    "di_sdf",
    "di_shading",
    "di_radiance_field",
    "neural_appearance",
    "uvfree_material",
    "appearance_prefilter",
    "imported",
    "hash_grid",
    "gltf_pbr",
)
