// A PBR texture set (Differentiable Indirection, Datta et al. 2023 4.2.1: "for PBR textures k includes albedo, normal, AO, roughness")
// shaded on a mesh: eight lanes (lib/pbr_sample's pbr_set_unpack). The compressed set (the DI
// bundle) and the uncompressed one (two RGBA8 textures of the same lanes) feed the same
// pbr_set_unpack and pbr_shade, so a side-by-side view differs by the compression alone.
// Shading: lib/pbr_shading with metallic 0 (the set has no metallic lane).
// Torch twin, same operations in the same order: models/pbr_lanes.py unpack, techniques/di_pbr_set/render.py shade.
#include <lib/pbr_sample>
#include <lib/pbr_shading>
