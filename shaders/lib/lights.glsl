// Lights of the scene (scene.json "lights"), uploaded by the runtime every frame. u_lights[i]: xyz
// the position (point) or the unit direction towards the light (directional), in the pass's space;
// w the intensity. u_light_kinds[i] says which (INSHADE_LIGHT_*, scene/description.py LIGHT_KINDS).
// u_scene_light_count is how many the scene has; a pass may light fewer (e.g. a "lights" setting).
// New passes call scene_light(); older ones read u_lights as point lights, and the runtime refuses
// them a directional light (u_light_kinds is then unused).
#define INSHADE_MAX_LIGHTS 4
#define INSHADE_LIGHT_POINT 0
#define INSHADE_LIGHT_DIRECTIONAL 1
uniform vec4 u_lights[INSHADE_MAX_LIGHTS];
uniform int u_light_kinds[INSHADE_MAX_LIGHTS];
uniform int u_scene_light_count;

int scene_lights(int wanted) {
    return clamp(wanted, 0, u_scene_light_count);
}

// Light i seen from p: the unit direction to the light, and what scales its intensity into
// irradiance (1 / distance^2 for a point light, 1 for a directional one). Multiply by
// u_lights[i].w and the cosine term.
void scene_light(int i, vec3 p, out vec3 to_light, out float irradiance_scale) {
    if (u_light_kinds[i] == INSHADE_LIGHT_DIRECTIONAL) {
        to_light = u_lights[i].xyz;
        irradiance_scale = 1.0;
    } else {
        vec3 d = u_lights[i].xyz - p;
        float d2 = max(dot(d, d), 1e-12);   // a light at p: finite, very bright, not NaN
        to_light = d * inversesqrt(d2);
        irradiance_scale = 1.0 / d2;
    }
}
