// Shadow-map depth pass, vertex stage: world -> the light's orthographic clip space (u_matrix,
// runtime/shadow.py light_matrices).

uniform mat4 u_matrix;

in vec3 in_position;

void main() {
    gl_Position = u_matrix * vec4(in_position, 1.0);
}
