// The vertex stage of a network drawn as an image by a three.js ShaderMaterial (inshade
// export-three): three declares position, uv and the matrices; the mesh's uv goes on to the network.
out vec2 v_inshade_uv;

void main() {
    v_inshade_uv = uv;
    gl_Position = projectionMatrix * modelViewMatrix * vec4(position, 1.0);
}
