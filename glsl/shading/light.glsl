// light.glsl: the lights every shading model sees, and the tone map.
//   vec3 tone_map(vec3 radiance)      exposure, Reinhard, then sRGB-ish gamma (tone_map_linear: before it)
//   vec3 shade_lights(vec3 T, vec3 N, vec3 V, vec3 color, float roughness, float occlusion,
//                     float keyTransmittance, ContainerShadow cs)
// The key light is directional (the user rotates it) and its shadow comes from the caller (traced or
// estimated through the container); the sky-over-ground ambient term is dimmed by ``occlusion``. Besides
// them, up to MAX_LIGHTS directional lights (app/render/look.py: apply_lighting): a fill and a rim light
// the user places, and the environment image cut into equal-energy pieces (app/render/environment.py).
// Each of those is dimmed by the fibers between the hit and the container's wall toward it (a density
// estimate on the straight cylinder: one traversal per light would cost too much). That is what makes a
// rim a rim: a back light reaches the fibers at a container's edge and barely the ones in front.
// SHADING_MODEL 0 Kajiya-Kay, 1 Marschner.

#include "common/epsilon.glsl"
#include "shading/kajiya_kay.glsl"
#include "shading/marschner.glsl"

#ifndef SHADING_LIGHT_GLSL
#define SHADING_LIGHT_GLSL

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

// before the display gamma: what the filtered mode composites (linear light)
vec3 tone_map_linear(vec3 c) {
    c *= uExposureScale;
    c = c / (1.0 + c);                              // Reinhard: highlights roll off instead of clipping
    return clamp(c, 0.0, 1.0);
}

vec3 tone_map(vec3 c) {
    return pow(tone_map_linear(c), vec3(1.0 / 2.2));
}

// Sky over ground: the fill light a fiber facing up sees more of.
vec3 ambient_fill(vec3 N, vec3 albedo, float occlusion) {
    return uAmbient * occlusion * albedo * (0.55 + 0.45 * max(N.z, 0.0));
}

struct ContainerShadow {
    mat3 containerFromWorld;    // the container's frame (axis = z)
    vec2 c;                     // the fiber's centre in the unit disc (1 = the container's wall)
    float density;              // fiber cross-section per unit length, times the shadow density; 0 = off
};

// Hair scatters mostly forward, so light goes deeper into a clump than the geometric estimate of the
// key light's shadow says; these broad lights take a quarter of its density (chosen by eye on the
// bundled presets: at 1 a rim or an HDRI lights only the outermost fibers).
const float FORWARD_SCATTER = 0.25;

// Light through a uniform medium from c to the unit circle along the light (xy part d of the unit
// direction): t solves |c + t d| = 1. Lights along the axis leave through a tip or root we do not know
// here: the path is capped at 4 container radii.
float density_transmittance(ContainerShadow cs, vec3 L) {
    vec3 Lc = cs.containerFromWorld * L;
    float dd = max(dot(Lc.xy, Lc.xy), EPS_LIGHT_AXIS2);
    float b = dot(cs.c, Lc.xy);
    float t = (-b + sqrt(max(b * b - dd * (dot(cs.c, cs.c) - 1.0), 0.0))) / dd;
    return exp(-FORWARD_SCATTER * cs.density * min(t, 4.0));
}

vec3 hair_model(vec3 T, vec3 N, vec3 V, vec3 L, vec3 color, float roughness) {
#if SHADING_MODEL == 1
    return shade_marschner(T, V, L, color, roughness);
#else
    return shade_kajiya_kay(T, N, V, L, color, roughness);
#endif
}

vec3 shade_lights(vec3 T, vec3 N, vec3 V, vec3 color, float roughness, float occlusion,
                  float keyTransmittance, ContainerShadow cs) {
    vec3 radiance = uLightIntensity * keyTransmittance * hair_model(T, N, V, uLightDir, color, roughness)
                  + ambient_fill(N, color, occlusion);
    for (int i = 0; i < uLightCount; i++) {
        radiance += uLightColors[i] * density_transmittance(cs, uLightDirs[i])
                  * hair_model(T, N, V, uLightDirs[i], color, roughness);
    }
    return radiance;
}

#endif
