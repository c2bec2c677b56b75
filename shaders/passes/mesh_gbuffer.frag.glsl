// Mesh G-buffer pass (deferred PRT on triangle meshes, Learnt Transfer, Dhawal et al. 2022 §4.1): rasterise the mesh once
// with depth testing (common/mesh.vert) so that a later full-screen pass runs the transfer
// network once per pixel, on the visible surface only.
// attachment 0: (world position, 1); attachment 1: (unit interpolated normal, 1); 2: (uv, material, 1);
// 3: (interpolated tangent, handedness); 4: uv footprint (dFdx(uv), dFdy(uv)): uv change per pixel
// along +x and +y (window axes), taken here where the triangle is known, since derivatives in the
// deferred pass would difference neighbours across triangle edges and uv seams. The clear value (0, 0, 0, 0) marks the background: w = 0. The normal is the mesh's own (outward for a
// consistently wound closed mesh), not flipped towards the viewer: transfer is a function of it.
// With GBUFFER_VISIBILITY (a visibility buffer): 5: the face index (uint; the mesh is drawn de-indexed in
// one draw, so vertex 3i + c is corner c of face i: the vertex pass sends gl_VertexID / 3, which ES 3.00
// has where it lacks gl_PrimitiveID); 6: perspective-correct barycentrics (t0, t1) of the
// face's vertices 0 and 1. With GBUFFER_UV1 (a texture reads TEXCOORD_1), at locations GBUFFER_UV1 and
// GBUFFER_UV1_DY: (uv1, dFdx(uv1)) and (dFdy(uv1), 0, 0). Built and read by runtime/geometry.py MeshGBuffer.
// <gbuffer_cutout> (lib/gbuffer_opaque, or lib/gltf_cutout for a glTF mesh with alphaMode MASK or BLEND
// materials): a fragment it cuts is discarded, so the depth test keeps what lies behind (and BLEND
// surfaces are drawn as layers of their own, peeled front to back).
#include <gbuffer_cutout>

in vec3 v_world_position;
in vec3 v_normal;
in vec2 v_uv;
in vec2 v_uv1;
in vec4 v_tangent;
flat in float v_material;

layout(location = 0) out vec4 out_position;
layout(location = 1) out vec4 out_normal;
layout(location = 2) out vec4 out_uv;
layout(location = 3) out vec4 out_tangent;
layout(location = 4) out vec4 out_uv_grad;
#ifdef GBUFFER_UV1
layout(location = GBUFFER_UV1) out vec4 out_uv1;
layout(location = GBUFFER_UV1_DY) out vec4 out_uv1_dy;
#endif
#ifdef GBUFFER_VISIBILITY
in vec2 v_barycentric;
flat in uint v_face;
layout(location = 5) out uint out_primitive;
layout(location = 6) out vec2 out_barycentric;
#endif

void main() {
    if (gbuffer_cut(v_uv, v_uv1, v_material, v_world_position)) discard;
    out_position = vec4(v_world_position, 1.0);
    // interpolation shortens the normal between vertices: renormalise per fragment
    out_normal = vec4(v_normal * (1.0 / length(v_normal)), 1.0);
    out_uv = vec4(v_uv, v_material, 1.0);
    out_tangent = v_tangent;
    out_uv_grad = vec4(dFdx(v_uv), dFdy(v_uv));
#ifdef GBUFFER_UV1
    out_uv1 = vec4(v_uv1, dFdx(v_uv1));
    out_uv1_dy = vec4(dFdy(v_uv1), 0.0, 0.0);
#endif
#ifdef GBUFFER_VISIBILITY
    out_primitive = v_face;
    out_barycentric = v_barycentric;
#endif
}
