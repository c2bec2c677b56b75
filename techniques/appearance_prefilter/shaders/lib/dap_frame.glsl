// The view-local frame of a direction w (unit, from the voxel TOWARD the viewer: w = -ray dir),
// shared by the per-voxel data (coverage masks, phase bins, incident directions) and the march.
// up = +y unless |w.y| > 0.999 (then +x); t = normalize(cross(up, w)); b = cross(w, t); (t, b, w)
// is right-handed. Python twin: techniques/appearance_prefilter/frame.py view_frame.
void dap_view_frame(vec3 w, out vec3 t, out vec3 b) {
    vec3 up = abs(w.y) > 0.999 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0);
    t = normalize(cross(up, w));
    b = cross(w, t);
}

// Bin centre (p, q) of the BT x BP equal-area phase bins, in the view-local frame (x = t, y = b,
// z = w): cos(theta) = 1 - (2p + 1) / BT, phi = 2 pi (q + 0.5) / BP measured from t toward b.
vec3 dap_bin_centre(int p, int q, int bins_theta, int bins_phi) {
    float c = 1.0 - float(2 * p + 1) / float(bins_theta);
    float s = sqrt(max(0.0, 1.0 - c * c));
    float phi = 6.28318531 * (float(q) + 0.5) / float(bins_phi);
    return vec3(s * cos(phi), s * sin(phi), c);
}
