// Full-screen triangle from gl_VertexID alone: draw 3 vertices with no buffers bound.
// The triangle (-1,-1), (3,-1), (-1,3) covers the viewport; v_uv is (0,0) at the bottom-left
// corner and (1,1) at the top-right, so at a pixel centre v_uv = (gl_FragCoord.xy) / size.

out vec2 v_uv;

void main() {
    vec2 corner = vec2(float((gl_VertexID & 1) << 2), float((gl_VertexID & 2) << 1));
    v_uv = corner * 0.5;
    gl_Position = vec4(corner - 1.0, 0.0, 1.0);
}
