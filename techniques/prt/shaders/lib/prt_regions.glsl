// Sub-scene transfer networks (Learnt Transfer, Dhawal et al. 2022 4.4): the network is chosen by the hit point's
// cell of a floor-plan grid (PRT_REGION_TABLE), and mixed with a neighbouring cell's network within
// a band along the cell sides where the two differ, so no seam shows (bilinear at corners).
// Included by the generated <prt_network> of a region set (techniques/prt/regions.py region_chunks),
// which defines PRT_REGION_* before it: the grid, the table and PRT_REGION_TERMS, one
// PRT_REGION_TERM(index, eval function, centre, inv_radius, scale) per network in order. Torch twin,
// same float32 operations:
// techniques/prt/regions.py blend_weights + techniques/prt/region_twin.py region_transfer.

// Own-network weight along one axis from the in-cell coordinate f: 1/2 on the cell side, 1 at
// 1 / inv_band inside (inv_band 0: a hard switch, always 1).
float prt_region_axis(float f, float inv_band) {
    float d = f < 0.5 ? f : 1.0 - f;
    return inv_band == 0.0 ? 1.0 : 0.5 + 0.5 * clamp(d * inv_band, 0.0, 1.0);
}

int prt_region_cell(int ix, int iz) {
    return PRT_REGION_TABLE[iz * PRT_REGION_NX + ix];
}

// Up to four (network, weight) pairs at world position p; unused slots have weight 0.
void prt_region_weights(vec3 p, out int nets[4], out float w[4]) {
    vec2 c = (p.xz - PRT_REGION_MIN) * PRT_REGION_INV_CELL;
    ivec2 ci = clamp(ivec2(floor(c)), ivec2(0), ivec2(PRT_REGION_NX - 1, PRT_REGION_NZ - 1));
    vec2 f = c - vec2(ci);
    ivec2 nb = ci + ivec2(f.x < 0.5 ? -1 : 1, f.y < 0.5 ? -1 : 1);
    bool hx = nb.x >= 0 && nb.x < PRT_REGION_NX;
    bool hz = nb.y >= 0 && nb.y < PRT_REGION_NZ;
    ivec2 nc = clamp(nb, ivec2(0), ivec2(PRT_REGION_NX - 1, PRT_REGION_NZ - 1));
    float ax = hx ? prt_region_axis(f.x, PRT_REGION_INV_BAND.x) : 1.0;
    float az = hz ? prt_region_axis(f.y, PRT_REGION_INV_BAND.y) : 1.0;
    nets[0] = prt_region_cell(ci.x, ci.y);
    nets[1] = prt_region_cell(nc.x, ci.y);
    nets[2] = prt_region_cell(ci.x, nc.y);
    nets[3] = prt_region_cell(nc.x, nc.y);
    w[0] = ax * az;
    w[1] = (1.0 - ax) * az;
    w[2] = ax * (1.0 - az);
    w[3] = (1.0 - ax) * (1.0 - az);
    for (int i = 1; i < 4; ++i) {       // one network named twice: its weights summed into the first slot
        for (int j = 0; j < i; ++j) {
            if (nets[j] == nets[i] && w[i] > 0.0 && w[j] > 0.0) {
                w[j] = w[j] + w[i];
                w[i] = 0.0;
            }
        }
    }
}

// Network r's weight among the four slots (duplicates were folded, so at most one slot names r).
float prt_region_weight(int r, in int nets[4], in float w[4]) {
    float wr = 0.0;
    for (int i = 0; i < 4; ++i) {
        wr = wr + (nets[i] == r ? w[i] : 0.0);
    }
    return wr;
}

// Network I's share of the blend (EVAL its eval function, its frame CENTER, INV_RADIUS, SCALE): run
// only where its weight is above 0 (a dynamic branch), in its own frame.
#define PRT_REGION_TERM(I, EVAL, CENTER, INV_RADIUS, SCALE) wr = prt_region_weight(I, nets, w); if (wr > 0.0) { x[0] = vec4((p - CENTER) * INV_RADIUS, n.x); x[1] = vec4(n.y, n.z, 0.0, 0.0); EVAL(x, y); for (int b = 0; b < 4; ++b) { t[b] = t[b] + wr * (y[b] * SCALE); } }

// The blended transfer at world p, normal n: each network's code once, accumulated in network
// order (region_twin.region_transfer).
void prt_region_blend(vec3 p, vec3 n, in int nets[4], in float w[4], out vec4 t[4]) {
    vec4 x[PRT_NET_IN_BLOCKS];
    vec4 y[PRT_NET_OUT_BLOCKS];
    for (int b = 0; b < 4; ++b) {
        t[b] = vec4(0.0);
    }
    float wr;
    PRT_REGION_TERMS
}

// PRT_NET_EVAL of a region set: x holds the world position and the normal (identity frame).
void prt_regions_eval(in vec4 x[PRT_NET_IN_BLOCKS], out vec4 y[PRT_NET_OUT_BLOCKS]) {
    vec3 p = x[0].xyz;
    vec3 n = vec3(x[0].w, x[1].x, x[1].y);
    int nets[4];
    float w[4];
    prt_region_weights(p, nets, w);
    vec4 t[4];
    prt_region_blend(p, n, nets, w, t);
    for (int b = 0; b < PRT_NET_OUT_BLOCKS; ++b) {
        y[b] = t[b];
    }
}
