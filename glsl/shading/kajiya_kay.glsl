// kajiya_kay.glsl: the fast hair model.
//   vec3 shade_kajiya_kay(vec3 T, vec3 N, vec3 V, vec3 L, vec3 albedo, float roughness)
// Kajiya-Kay with two shifted lobes: a white primary highlight shifted toward the root and a tinted,
// wider secondary one toward the tip, plus a Lambert term on the true fiber normal so round fibers
// read as round. Returns reflected radiance per unit light intensity.

#ifndef SHADING_KAJIYA_KAY_GLSL
#define SHADING_KAJIYA_KAY_GLSL

float kajiya_kay_lobe(vec3 T, vec3 V, vec3 L, float shift, float exponent) {
    vec3 Ts = normalize(T + shift * cross(T, cross(V, T)));
    float tl = dot(Ts, L);
    float tv = dot(Ts, V);
    // V lies on the cone of mirror directions of L about the fiber when angle(T, V) = pi - angle(T, L)
    float c = sqrt(max(0.0, 1.0 - tl * tl)) * sqrt(max(0.0, 1.0 - tv * tv)) - tl * tv;
    return pow(max(c, 0.0), exponent);
}

vec3 shade_kajiya_kay(vec3 T, vec3 N, vec3 V, vec3 L, vec3 albedo, float roughness) {
    float tl = dot(T, L);
    float diffuse = mix(sqrt(max(0.0, 1.0 - tl * tl)), max(dot(N, L), 0.0), 0.5);
    float exponent = 2.0 / max(roughness * roughness, 1e-4);
    float primary = kajiya_kay_lobe(T, V, L, -0.1, exponent);
    float secondary = kajiya_kay_lobe(T, V, L, 0.15, 0.5 * exponent);
    return albedo * diffuse * 0.8 + 0.12 * vec3(primary) + 0.25 * albedo * secondary;
}

#endif
