// Progressive accumulation (runtime/renderer.py, ProgramSpec.accumulate): folds the newest Monte
// Carlo sample into the running mean of the samples so far, for each of ACCUMULATE_ATTACHMENTS
// (1..8, a #define) colour attachments: mean_n = mean_{n-1} + (x - mean_{n-1}) / n, in float32.
// Ping-pong: u_mean<k> is last frame's mean target, the output a second target of the same size.
// Texel = pixel (same-size NEAREST targets, texelFetch), so no filtering touches the data.

uniform int u_count;   // n: samples including this one (1 = the first: the mean is the sample)

// One attachment's new mean. n == 1 ignores the old target (its contents are stale or undefined).
vec4 running_mean(sampler2D mean_tex, sampler2D sample_tex, ivec2 px) {
    vec4 x = texelFetch(sample_tex, px, 0);
    if (u_count <= 1) {
        return x;
    }
    vec4 mean = texelFetch(mean_tex, px, 0);
    return mean + (x - mean) / float(u_count);
}

// Samplers cannot be indexed by a loop variable in GLSL 3.30, hence one block per attachment.
uniform sampler2D u_mean0;
uniform sampler2D u_sample0;
layout(location = 0) out vec4 out_mean0;
#if ACCUMULATE_ATTACHMENTS > 1
uniform sampler2D u_mean1;
uniform sampler2D u_sample1;
layout(location = 1) out vec4 out_mean1;
#endif
#if ACCUMULATE_ATTACHMENTS > 2
uniform sampler2D u_mean2;
uniform sampler2D u_sample2;
layout(location = 2) out vec4 out_mean2;
#endif
#if ACCUMULATE_ATTACHMENTS > 3
uniform sampler2D u_mean3;
uniform sampler2D u_sample3;
layout(location = 3) out vec4 out_mean3;
#endif
#if ACCUMULATE_ATTACHMENTS > 4
uniform sampler2D u_mean4;
uniform sampler2D u_sample4;
layout(location = 4) out vec4 out_mean4;
#endif
#if ACCUMULATE_ATTACHMENTS > 5
uniform sampler2D u_mean5;
uniform sampler2D u_sample5;
layout(location = 5) out vec4 out_mean5;
#endif
#if ACCUMULATE_ATTACHMENTS > 6
uniform sampler2D u_mean6;
uniform sampler2D u_sample6;
layout(location = 6) out vec4 out_mean6;
#endif
#if ACCUMULATE_ATTACHMENTS > 7
uniform sampler2D u_mean7;
uniform sampler2D u_sample7;
layout(location = 7) out vec4 out_mean7;
#endif

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    out_mean0 = running_mean(u_mean0, u_sample0, px);
#if ACCUMULATE_ATTACHMENTS > 1
    out_mean1 = running_mean(u_mean1, u_sample1, px);
#endif
#if ACCUMULATE_ATTACHMENTS > 2
    out_mean2 = running_mean(u_mean2, u_sample2, px);
#endif
#if ACCUMULATE_ATTACHMENTS > 3
    out_mean3 = running_mean(u_mean3, u_sample3, px);
#endif
#if ACCUMULATE_ATTACHMENTS > 4
    out_mean4 = running_mean(u_mean4, u_sample4, px);
#endif
#if ACCUMULATE_ATTACHMENTS > 5
    out_mean5 = running_mean(u_mean5, u_sample5, px);
#endif
#if ACCUMULATE_ATTACHMENTS > 6
    out_mean6 = running_mean(u_mean6, u_sample6, px);
#endif
#if ACCUMULATE_ATTACHMENTS > 7
    out_mean7 = running_mean(u_mean7, u_sample7, px);
#endif
}
