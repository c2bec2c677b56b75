// The output a field pass shows of its network <network>: FIELD_OUT_DIM lanes from lane
// FIELD_OUT_OFFSET of the concatenated outputs (runtime/scene_program.py sets both from the
// bundle's `render` field; by default the first three).
#include <network>

#ifndef FIELD_OUT_OFFSET
#define FIELD_OUT_OFFSET 0
#endif
#ifndef FIELD_OUT_DIM
#define FIELD_OUT_DIM 3
#endif

float field_lane(in vec4 y[NET_OUT_BLOCKS], int lane) {
    return y[lane / 4][lane % 4];
}

// The shown colour: grey for a one-lane output, else its first three lanes.
vec3 field_rgb(in vec4 y[NET_OUT_BLOCKS]) {
#if FIELD_OUT_DIM == 1
    return vec3(field_lane(y, FIELD_OUT_OFFSET));
#else
    return vec3(field_lane(y, FIELD_OUT_OFFSET), field_lane(y, FIELD_OUT_OFFSET + 1),
                field_lane(y, FIELD_OUT_OFFSET + 2));
#endif
}
