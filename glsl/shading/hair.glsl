// hair.glsl: shading of one fiber hit.
//   vec3 shade_fiber(vec3 T, vec3 N, vec3 V, vec3 albedo, float roughness, float occlusion)
// Kajiya-Kay with two shifted lobes (a white primary highlight shifted toward the root and a tinted
// secondary one toward the tip), plus a Lambert term on the true fiber normal so that round fibers read
// as round. Light and fill come from uniforms; the result is linear radiance, tone-mapped by the caller.

uniform vec3 uLightDir;         // toward the light, world
uniform float uLightIntensity;
uniform float uAmbient;

float kajiya_kay_spec(vec3 T, vec3 V, vec3 L, float shift, float exponent) {
    vec3 Ts = normalize(T + shift * cross(T, cross(V, T)));
    float tl = dot(Ts, L);
    float tv = dot(Ts, V);
    float c = tl * tv + sqrt(max(0.0, 1.0 - tl * tl)) * sqrt(max(0.0, 1.0 - tv * tv));
    return pow(max(c, 0.0), exponent);
}

vec3 shade_fiber(vec3 T, vec3 N, vec3 V, vec3 albedo, float roughness, float occlusion) {
    vec3 L = uLightDir;
    float tl = dot(T, L);
    float kkDiffuse = sqrt(max(0.0, 1.0 - tl * tl));
    float lambert = max(dot(N, L), 0.0);
    float diffuse = mix(kkDiffuse, lambert, 0.5);
    float exponent = 2.0 / max(roughness * roughness, 1e-4);
    float spec1 = kajiya_kay_spec(T, V, L, -0.1, exponent);
    float spec2 = kajiya_kay_spec(T, V, L, 0.15, exponent * 0.5);
    vec3 direct = uLightIntensity * occlusion * (albedo * diffuse + 0.25 * vec3(spec1) + 0.4 * albedo * spec2);
    vec3 fill = uAmbient * occlusion * albedo * (0.6 + 0.4 * max(N.z, 0.0));
    return direct + fill;
}

vec3 tone_map(vec3 c) {
    c = c / (1.0 + c);                              // Reinhard: keeps highlights from clipping hard
    return pow(clamp(c, 0.0, 1.0), vec3(1.0 / 2.2));
}
