// Camera rays for full-screen passes (SDF sphere tracing, deferred mesh shading, ray-cast planes).
// World frame: right-handed, y up; the camera looks down -z (scene/camera.py).
// Torch twin: models/sdf.py camera_rays.

uniform mat4 u_inv_view_proj;  // inverse of proj * view (scene/camera.py)
uniform vec3 u_eye;            // camera position

// Ray through the pixel centre frag (gl_FragCoord.xy): the far-plane point (ndc z = 1)
// unprojected, minus the eye, normalised (the far point keeps float32 cancellation small).
void camera_ray(vec2 frag, vec2 size, out vec3 ro, out vec3 rd) {
    vec2 ndc = frag * (2.0 / size) - 1.0;
    vec4 w = u_inv_view_proj * vec4(ndc, 1.0, 1.0);
    vec3 far_point = w.xyz * (1.0 / w.w);
    ro = u_eye;
    vec3 d = far_point - u_eye;
    rd = d * (1.0 / length(d));
}
