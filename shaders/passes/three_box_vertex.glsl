// The vertex stage of an SDF or a field drawn by a three.js ShaderMaterial (inshade export-three): the
// mesh is a box around the SDF's bound sphere or the field's box, drawn from the inside (back faces),
// so every view ray through it reaches the fragment stage with the camera's position, both in the
// scene's frame (the mesh's).
out vec3 v_inshade_ro;
out vec3 v_inshade_p;

void main() {
    v_inshade_ro = (inverse(modelMatrix) * vec4(cameraPosition, 1.0)).xyz;
    v_inshade_p = position;
    gl_Position = projectionMatrix * modelViewMatrix * vec4(position, 1.0);
}
