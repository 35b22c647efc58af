#version 450 core
// container.frag: per pixel, rebuild the view ray, enter the container's unit space, traverse the
// virtual fibers and write the nearest hit (colour, ids, normal, true depth) or discard.
// COST_PASS: instead write the work done (fiber tests, arcs, 1, loop iterations) for additive blending.

#include "fibers/traverse.glsl"
#include "shading/hair.glsl"

flat in vec4 vA;
flat in vec4 vB;
flat in vec4 vC;
flat in vec4 vD;
flat in vec4 vE;
flat in int vSegment;

uniform vec3 uCamRight;         // world-space camera basis, scaled by tan(fov/2) (and aspect)
uniform vec3 uCamUp;
uniform vec3 uCamForward;
uniform vec2 uViewport;
uniform vec2 uPixelOffset;      // sub-pixel offset of the ray (antialiasing, stability tests)
uniform float uNear;
uniform float uFar;
uniform vec3 uBaseColor;
uniform float uRoughness;
uniform float uTintVariation;
uniform float uRoughnessVariation;
uniform float uShadowDensity;

#ifndef COST_PASS
#define COST_PASS 0
#endif

#if COST_PASS
layout(location = 0) out vec4 outCost;
#else
layout(location = 0) out vec4 outColor;
layout(location = 1) out uvec4 outId;       // guide + 1, ring, fiber, segment
layout(location = 2) out vec4 outGeom;      // world normal, distance along the ray
#endif

void main() {
    vec2 ndc = (gl_FragCoord.xy + uPixelOffset) / uViewport * 2.0 - 1.0;
    vec3 rd = normalize(uCamForward + ndc.x * uCamRight + ndc.y * uCamUp);
    Segment seg = make_segment(vA, vB, vC, vD, vE);
    UnitRay ur;
    if (!to_unit_space(seg, vec3(0.0), rd, uNear, ur)) discard;
    FiberHit hit = traverse(seg, ur);
#if COST_PASS
    outCost = vec4(float(gTests), float(gPieces), 1.0, float(gIters));
#else
    if (hit.s >= INF) discard;
    float t = unit_to_world_t(seg, ur, hit.s);
    // the true depth of the fiber inside the container (logarithmic: near 1e-4 and far 1e6 both work)
    gl_FragDepth = clamp(log(max(t, uNear) / uNear) / log(uFar / uNear), 0.0, 1.0);

    vec3 P = ur.O + hit.s * ur.D;               // unit space
    vec3 nLocal;
    if (hit.kind == 0) {
        vec2 radial = P.xy - hit.c;
        nLocal = vec3(radial, -seg.kappa * dot(radial, P.xy));
    } else if (hit.kind == 1) {
        nLocal = vec3(0.0, 0.0, 1.0);
    } else {
        nLocal = -ur.d;                          // a fiber cut by a cap or joint: its section faces us
    }
    mat3 worldFromLocal = mat3(seg.ex, seg.ey, seg.ez);
    vec3 N = normalize(worldFromLocal * nLocal);
    // the fiber's direction: d/dz of (w(z) c(v(z)), z), w the local container radius at the hit
    float wHit = seg.r0 / (1.0 - seg.kappa * P.z);
    vec2 slope = seg.kappa * hit.c + wHit * hit.dcdv * (seg.v1 - seg.v0) / seg.h;
    vec3 T = normalize(worldFromLocal * vec3(slope, 1.0));
    vec3 V = -rd;
    if (dot(N, V) < 0.0) N = -N;

    float tint = fiber_random(uSeed, seg.guide, uint(hit.ring), uint(hit.fiber), CH_TINT) - 0.5;
    float rough = fiber_random(uSeed, seg.guide, uint(hit.ring), uint(hit.fiber), CH_ROUGH) - 0.5;
    vec3 albedo = clamp(uBaseColor * (1.0 + uTintVariation * 2.0 * tint), 0.0, 1.0);
    float roughness = clamp(uRoughness * (1.0 + uRoughnessVariation * 2.0 * rough), 0.02, 1.0);
    // density self-shadowing: fibers deep in the container see less light and sky
    float depthIn = 1.0 - length(hit.c);
    float occlusion = mix(1.0, exp(-3.0 * depthIn), uShadowDensity);

    outColor = vec4(tone_map(shade_fiber(T, N, V, albedo, roughness, occlusion)), 1.0);
    outId = uvec4(seg.guide + 1u, uint(hit.ring), uint(hit.fiber), uint(vSegment));
    outGeom = vec4(N, t);
#endif
}
