// Shadow-map depth pass: the window depth, clip z * 0.5 + 0.5 (orthographic), into an R32F
// colour target (runtime/shadow.py copies it into one layer of the shadow-map array).

out float out_depth;

void main() {
    out_depth = gl_FragCoord.z;
}
