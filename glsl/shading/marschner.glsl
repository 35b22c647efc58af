// marschner.glsl: a real-time Marschner model (R, TT, TRT lobes).
//   vec3 shade_marschner(vec3 T, vec3 V, vec3 L, vec3 color, float roughness)
// Longitudinal lobes are Gaussians in theta_h shifted by the cuticle tilt (R -2a, TT +a, TRT +4a) with
// widths beta, beta/2, 2 beta; azimuthal terms follow Karis's fits (SIGGRAPH 2016 "Physically based
// hair shading in Unreal"): R ~ cos(phi/2), TT peaks in forward scattering, TRT gives the coloured glint.
// ``color`` is what one pass through a fiber lets through, so TT and TRT are tinted by powers of it.

#ifndef SHADING_MARSCHNER_GLSL
#define SHADING_MARSCHNER_GLSL

const float HAIR_F0 = 0.04652;          // Fresnel at normal incidence, eta = 1.55
const float CUTICLE_TILT = 0.035;       // radians (about 2 degrees)

float hair_gaussian(float beta, float x) {
    return exp(-0.5 * x * x / (beta * beta)) / (2.50662827 * beta);
}

float hair_fresnel(float cosTheta) {
    float m = 1.0 - clamp(cosTheta, 0.0, 1.0);
    return HAIR_F0 + (1.0 - HAIR_F0) * m * m * m * m * m;
}

vec3 shade_marschner(vec3 T, vec3 V, vec3 L, vec3 color, float roughness) {
    float sinL = clamp(dot(T, L), -1.0, 1.0);
    float sinV = clamp(dot(T, V), -1.0, 1.0);
    float cosD = cos(0.5 * abs(asin(sinV) - asin(sinL)));
    vec3 Lp = L - sinL * T;
    vec3 Vp = V - sinV * T;
    float cosPhi = dot(Lp, Vp) * inversesqrt(dot(Lp, Lp) * dot(Vp, Vp) + 1e-4);
    float cosHalfPhi = sqrt(clamp(0.5 + 0.5 * cosPhi, 0.0, 1.0));
    float beta = max(roughness * roughness, 0.01);
    vec3 S = vec3(0.0);
    // R: white reflection off the cuticle
    float sa = sin(-2.0 * CUTICLE_TILT), ca = cos(-2.0 * CUTICLE_TILT);
    float shift = 2.0 * sa * (ca * cosHalfPhi * sqrt(1.0 - sinV * sinV) + sa * sinV);
    float Mr = hair_gaussian(beta * 1.41421356 * max(cosHalfPhi, 0.05), sinL + sinV - shift);
    S += vec3(Mr * 0.25 * cosHalfPhi * hair_fresnel(sqrt(clamp(0.5 + 0.5 * dot(V, L), 0.0, 1.0))));
    // TT: light through the fiber, strongest when the light is behind it
    float nPrime = 1.19 / cosD + 0.36 * cosD;
    float a = 1.0 / nPrime;
    float h = cosHalfPhi * (1.0 + a * (0.6 - 0.8 * cosPhi));
    float f = hair_fresnel(cosD * sqrt(clamp(1.0 - h * h, 0.0, 1.0)));
    vec3 Ttt = pow(color, vec3(0.5 * sqrt(max(0.0, 1.0 - h * h * a * a)) / cosD));
    S += hair_gaussian(0.5 * beta, sinL + sinV - CUTICLE_TILT) * exp(-3.65 * cosPhi - 3.98)
         * (1.0 - f) * (1.0 - f) * Ttt;
    // TRT: internal reflection, the coloured secondary highlight
    f = hair_fresnel(0.5 * cosD);
    S += hair_gaussian(2.0 * beta, sinL + sinV - 4.0 * CUTICLE_TILT) * exp(17.0 * cosPhi - 16.78)
         * (1.0 - f) * (1.0 - f) * f * pow(color, vec3(0.8 / cosD));
    // a diffuse floor for multiple scattering between fibers, which the three lobes leave out
    return S + color * 0.25 * sqrt(max(0.0, 1.0 - sinL * sinL));
}

#endif
