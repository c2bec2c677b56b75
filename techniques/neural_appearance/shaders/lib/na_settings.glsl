// The settings both neural-appearance passes (the technique's own material and a glTF file's) read:
// the view (NA_VIEW_*), the lighting and the environment estimator (NA_LIGHTING_*, NA_SAMPLING_*,
// MIS on or off), the pyramid level bias, the error view's scale, the scene's light count and the
// sample index the random numbers are drawn with (ProgramSpec.accumulate).
uniform int u_sample_index;
uniform int u_na_view;
uniform int u_na_lighting;
uniform int u_na_sampling;
uniform int u_na_mis;
uniform int u_light_count;
uniform float u_na_level_bias;
uniform float u_na_error_scale;
