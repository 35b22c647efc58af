// light.glsl: the lights every shading model sees, and the tone map.
//   vec3 tone_map(vec3 radiance)      exposure, Reinhard, then sRGB-ish gamma
// The key light is directional (the user rotates it); the fill is a sky-over-ground ambient term.

uniform vec3 uLightDir;         // toward the light, world
uniform float uLightIntensity;
uniform float uAmbient;
uniform float uExposureScale;   // 2^exposure stops (computed once by the renderer, not per fragment)

vec3 tone_map(vec3 c) {
    c *= uExposureScale;
    c = c / (1.0 + c);                              // Reinhard: highlights roll off instead of clipping
    return pow(clamp(c, 0.0, 1.0), vec3(1.0 / 2.2));
}

// Sky over ground: the fill light a fiber facing up sees more of.
vec3 ambient_fill(vec3 N, vec3 albedo, float occlusion) {
    return uAmbient * occlusion * albedo * (0.55 + 0.45 * max(N.z, 0.0));
}
