// Point lights of the scene (scene.json "lights"), uploaded by the runtime every frame: xyz the
// position in the pass's space, w the intensity (inverse-square falloff). u_scene_light_count is
// how many the scene has; a pass may light fewer (e.g. a "lights" setting).
#define INSHADE_MAX_LIGHTS 4
uniform vec4 u_lights[INSHADE_MAX_LIGHTS];
uniform int u_scene_light_count;

int scene_lights(int wanted) {
    return clamp(wanted, 0, u_scene_light_count);
}
