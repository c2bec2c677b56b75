// The G-buffer pass's cut-out test for meshes without alpha-masked or blended materials: nothing is
// cut out. (passes/mesh_gbuffer includes <gbuffer_cutout>: this chunk, or lib/gltf_cutout.)
bool gbuffer_cut(vec2 uv, vec2 uv1, float material, vec3 p) { return false; }
