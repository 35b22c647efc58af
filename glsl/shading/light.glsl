// light.glsl: the lights every shading model sees, and the tone map.
//   vec3 tone_map(vec3 radiance)      exposure, Reinhard, then sRGB-ish gamma
//   vec3 shade_lights(vec3 T, vec3 N, vec3 V, vec3 color, float roughness, float occlusion,
//                     float keyTransmittance)
// The key light is directional (the user rotates it) and its shadow comes from the caller (traced or
// estimated through the container); the fill is a sky-over-ground ambient term. Besides them, up to
// MAX_LIGHTS directional lights (app/render/look.py: apply_lighting): a fill and a rim light the user
// places, and the environment image cut into equal-energy pieces (app/render/environment.py). Those see
// the fiber's sky occlusion instead of a traced shadow: one traversal per light would cost too much.
// SHADING_MODEL 0 Kajiya-Kay, 1 Marschner.

#include "shading/kajiya_kay.glsl"
#include "shading/marschner.glsl"

#ifndef SHADING_MODEL
#define SHADING_MODEL 0
#endif
#define MAX_LIGHTS 12

uniform vec3 uLightDir;         // toward the light, world
uniform float uLightIntensity;
uniform float uAmbient;
uniform float uExposureScale;   // 2^exposure stops (computed once by the renderer, not per fragment)
uniform int uLightCount;        // lights besides the key in uLightDirs/uLightColors (0: none)
uniform vec3 uLightDirs[MAX_LIGHTS];
uniform vec3 uLightColors[MAX_LIGHTS];  // linear RGB times intensity

vec3 tone_map(vec3 c) {
    c *= uExposureScale;
    c = c / (1.0 + c);                              // Reinhard: highlights roll off instead of clipping
    return pow(clamp(c, 0.0, 1.0), vec3(1.0 / 2.2));
}

// Sky over ground: the fill light a fiber facing up sees more of.
vec3 ambient_fill(vec3 N, vec3 albedo, float occlusion) {
    return uAmbient * occlusion * albedo * (0.55 + 0.45 * max(N.z, 0.0));
}

vec3 hair_model(vec3 T, vec3 N, vec3 V, vec3 L, vec3 color, float roughness) {
#if SHADING_MODEL == 1
    return shade_marschner(T, V, L, color, roughness);
#else
    return shade_kajiya_kay(T, N, V, L, color, roughness);
#endif
}

vec3 shade_lights(vec3 T, vec3 N, vec3 V, vec3 color, float roughness, float occlusion,
                  float keyTransmittance) {
    vec3 radiance = uLightIntensity * keyTransmittance * hair_model(T, N, V, uLightDir, color, roughness)
                  + ambient_fill(N, color, occlusion);
    vec3 others = vec3(0.0);
    for (int i = 0; i < uLightCount; i++) {
        others += uLightColors[i] * hair_model(T, N, V, uLightDirs[i], color, roughness);
    }
    return radiance + occlusion * others;
}
