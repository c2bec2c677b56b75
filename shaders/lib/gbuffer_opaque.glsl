// The G-buffer pass's cut-out test for meshes without alpha-masked materials: nothing is cut out.
// (passes/mesh_gbuffer includes <gbuffer_cutout>: this chunk, or lib/gltf_cutout.)
bool gbuffer_cut(vec2 uv, float material) { return false; }
