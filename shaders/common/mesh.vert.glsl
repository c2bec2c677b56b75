// Mesh vertex shader: object space -> world (u_model) -> camera (u_view) -> clip (u_proj).
// Matrices are column-major GLSL mat4; right-handed, y up, the camera looks down -z.
// Normals use the inverse-transpose of u_model, so non-uniform scales stay correct.

uniform mat4 u_model;
uniform mat4 u_view;
uniform mat4 u_proj;

in vec3 in_position;
in vec3 in_normal;
in vec2 in_uv;
in vec4 in_tangent;   // (tangent along +u, handedness); zero for meshes without uv
in float in_material; // the face's material (a glTF mesh's index into its materials; 0 otherwise)
#ifdef GBUFFER_UV1
in vec2 in_uv1;       // a glTF mesh's TEXCOORD_1 (v up), where a texture reads it
#endif
out vec2 v_uv1;       // in_uv without a second set
#ifdef GBUFFER_VISIBILITY
in vec2 in_barycentric;   // the corner's unit barycentrics (t0, t1): the mesh is drawn de-indexed
out vec2 v_barycentric;
flat out uint v_face;     // gl_VertexID / 3: the face index (ES 3.00 has no gl_PrimitiveID)
#endif

out vec3 v_world_position;
out vec3 v_normal;
out vec2 v_uv;
out vec4 v_tangent;
flat out float v_material;

void main() {
    vec4 world = u_model * vec4(in_position, 1.0);
    v_world_position = world.xyz;
    v_normal = normalize(transpose(inverse(mat3(u_model))) * in_normal);
    v_uv = in_uv;
#ifdef GBUFFER_UV1
    v_uv1 = in_uv1;
#else
    v_uv1 = in_uv;
#endif
    v_material = in_material;
    v_tangent = vec4(mat3(u_model) * in_tangent.xyz, in_tangent.w);
#ifdef GBUFFER_VISIBILITY
    v_barycentric = in_barycentric;
    v_face = uint(gl_VertexID / 3);
#endif
    gl_Position = u_proj * u_view * world;
}
