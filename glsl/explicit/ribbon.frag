#version 450 core
// ribbon.frag: shade an explicit fiber's ribbon as the round fiber it stands for, with the virtual
// renderer's shading files and terms (stages/container.frag: trace_and_shade): the same per-fiber tint and
// roughness, sky occlusion by depth in the container, density self-shadow, shading model and tone map.
// SHADING_MODEL 0 Kajiya-Kay, 1 Marschner.
// FILTER (quality.filter = coverage; app/render/explicit.py draws the widened ribbons three times, no depth
// test): each fragment covers footprint_coverage(x, r, w) of its pixel's footprint (fibers/coverage.glsl,
// the virtual filter's tent), which becomes its alpha, and the pixel composites its fragments by depth
// without sorting them:
//   1  the nearest fragment's distance (MIN blending)
//   2  optical depth -log(1 - alpha) summed into 16 depth bins of uBinWidth behind that (additive)
//   3  each fragment's linear colour weighted by alpha and the transmittance in front of it, read from the
//      bins (light through the bins before its own, and the share of its own bin in front of it), and its
//      optical depth (additive); fragments behind the pixel's opaque depth (cutoff.frag, in the depth
//      buffer) fail the early depth test and are never shaded; COMPOSITE 1 weighs by alpha and an exponential of the depth behind the
//      nearest instead (weighted blended OIT, the alternative measured in docs/antialias.md)
// The explicit renderer resolves: alpha = 1 - exp(-total optical depth), colour = the weighted mean.

#include "common/epsilon.glsl"
#include "shading/light.glsl"
#include "shading/kajiya_kay.glsl"
#include "shading/marschner.glsl"
#include "shading/fiber_color.glsl"
#include "shading/tangent.glsl"

#ifndef SHADING_MODEL
#define SHADING_MODEL 0
#endif
#ifndef TAPER
#define TAPER 0
#endif
#ifndef FILTER
#define FILTER 0
#endif
#ifndef COMPOSITE
#define COMPOSITE 0
#endif
#if FILTER
#include "fibers/coverage.glsl"
#define BINS 16
#ifndef WEIGHT_FALLOFF
#define WEIGHT_FALLOFF 0.5     // COMPOSITE 1: the weight falls by e every 2 bins behind the nearest fragment
#endif
uniform sampler2D uNearest;     // pass 1: the nearest fragment's distance per pixel
uniform sampler2D uBins0;       // pass 2: optical depth in bins 0-3, 4-7, 8-11, 12-15
uniform sampler2D uBins1;
uniform sampler2D uBins2;
uniform sampler2D uBins3;
uniform float uBinWidth;        // depth of a bin, world units (explicit.py: BIN_RADII container radii)
in vec3 vCross;                 // offset across the fiber, its radius, the footprint's half-width (ribbon.vert)
#endif

in vec3 vPos;
in vec3 vTangent;
in vec2 vJoint;                 // distance from the root and tip joint planes (ribbon.vert)
flat in vec3 vJointN0;
flat in vec3 vJointN1;
flat in vec3 vSlope;
in float vAcross;
in vec4 vInside;                // offset of the fiber's axis from the container's axis (w d), height z
in float vRadius;               // container radius w
flat in vec4 vAxis;             // container segment axis (unit), length h
flat in vec2 vEnds;             // 1: the segment is the guide's root / tip
flat in vec2 vRadii;            // the container radius at the root and tip end (ribbon.vert)
flat in uvec4 vId;
flat in vec3 vLook;
in float vV;                    // guide parameter at this point of the ribbon
flat in float vTilt;            // the fiber's radius falls this much per unit length (its tapered tip)
flat in float vFiberRadius;     // the fiber's ring's radius (ribbon.vert)

uniform float uRoughness;
uniform float uRoughnessVariation;
uniform float uShadowDensity;
uniform float uFiberDensity;    // fiber cross-section per unit length of a light path, unit space

#ifndef SHADOW_MODE
#define SHADOW_MODE 1
#endif

#if FILTER == 0
layout(location = 0) out vec4 outColor;
layout(location = 1) out uvec4 outId;       // guide + 1, ring, fiber, segment
layout(location = 2) out vec4 outGeom;      // world normal, distance along the ray
#elif FILTER == 2
layout(location = 0) out vec4 outBins0;
layout(location = 1) out vec4 outBins1;
layout(location = 2) out vec4 outBins2;
layout(location = 3) out vec4 outBins3;
#else
layout(location = 0) out vec4 outValue;     // 1: distance; 3: weighted linear colour, weight
layout(location = 1) out vec4 outDepth;     // 3: optical depth
#endif
#if FILTER == 3 && COMPOSITE == 0
// the depth test before the shader: cutoff.frag put each pixel's opaque distance in the depth buffer
layout(early_fragment_tests) in;
#endif

// Density self-shadow as the virtual renderer estimates it (shading/fiber_shading.glsl: light_transmittance):
// the fibers as a uniform medium along the light's path from the shaded point to the wall of the blended
// guide's cylinder (shading/tangent.glsl: joint_light_path, which runs on across joints), or past the
// guide's root or tip, in container radii. P: the point's offset from its fiber's axis point.
float light_through(vec3 P, vec3 L) {
#if SHADOW_MODE == 0
    return 1.0;
#else
    vec3 axis = vAxis.xyz;
    float z = vInside.w + dot(P, axis);
    vec3 offset = vInside.xyz + P - dot(P, axis) * axis;     // from the axis (a reference strand's depth too)
    vec3 fromRoot = z * axis + offset - dot(offset, axis) * axis;
    vec3 tip = vAxis.w * axis;
    float path = joint_light_path_in(joint_light_frame(vJointN0, vJointN1, tip, fromRoot, L), vJointN0, vJointN1, tip,
                                     vRadii, greaterThan(vEnds, vec2(0.5)), fromRoot, offset, L);
    return exp(-uShadowDensity * uFiberDensity * path);
#endif
}

#if FILTER
// Transmittance in front of a fragment k bins behind the nearest: the bins before its own, and of its own
// the share in front of it (optical depth spread evenly through a bin).
float transmittance_before(float k) {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec4 b[4] = vec4[4](texelFetch(uBins0, px, 0), texelFetch(uBins1, px, 0), texelFetch(uBins2, px, 0),
                        texelFetch(uBins3, px, 0));
    int own = min(int(k), BINS - 1);
    float share = k >= float(BINS) ? 0.5 : fract(k);
    float tau = 0.0;
    for (int i = 0; i < BINS; i++) {
        float bin = b[i >> 2][i & 3];
        tau += i < own ? bin : (i == own ? share * bin : 0.0);
    }
    return exp(-tau);
}
#endif

void main() {
#if FILTER
    float a = footprint_coverage(abs(vCross.x), vCross.y, vCross.z);
    if (!(a > 0.0)) discard;
    a = min(a, 0.9999);                         // a fiber wider than its footprint: opaque but finite depth
    float dist = length(vPos);
#if FILTER == 1
    outValue = vec4(dist, 0.0, 0.0, 0.0);
    outDepth = vec4(0.0);
    return;
#else
    float sigma = -log(1.0 - a);
    float k = max(dist - texelFetch(uNearest, ivec2(gl_FragCoord.xy), 0).x, 0.0) / uBinWidth;
#if FILTER == 2
    int bin = min(int(k), BINS - 1);
    vec4 one = vec4(equal(ivec4(0, 1, 2, 3), ivec4(bin & 3))) * sigma;
    outBins0 = bin >> 2 == 0 ? one : vec4(0.0);
    outBins1 = bin >> 2 == 1 ? one : vec4(0.0);
    outBins2 = bin >> 2 == 2 ? one : vec4(0.0);
    outBins3 = bin >> 2 == 3 ? one : vec4(0.0);
    return;
#endif
#endif
#endif
    vec3 V = normalize(-vPos);
    vec3 R = normalize(vTangent);
    // the round fiber's normal: sideways across the ribbon, toward the viewer in its middle
    vec3 S = normalize(cross(R, V));
    vec3 F = cross(S, R);
#if FILTER
    // the middle of the fiber's covered part and its surface facing the ray (fibers/coverage.glsl does so)
    float lo = max(-vCross.y, vCross.x - vCross.z);
    float hi = min(vCross.y, vCross.x + vCross.z);
    float u = clamp(0.5 * (lo + hi) / max(vCross.y, 1e-30), -1.0, 1.0);
#else
    float u = clamp(vAcross, -1.0, 1.0);
#endif
    vec3 N = normalize(S * u + F * sqrt(max(0.0, 1.0 - u * u)));
#if TAPER
    // a cone's normal leans toward its apex: n - R'(s) T for a radius R falling along the fiber
    N = normalize(N + vTilt * R);
#endif
    vec3 T = normalize(joint_blend(vJointN0, vJointN1, vJoint.x, vJoint.y) + vSlope);
    // the shading normal turns with the tangent, as the virtual fiber's (shading/tangent.glsl)
    vec3 Ns = turn_with(N, R, T);

    vec3 color = fiber_color(vId.x - 1u, vV, vLook.x - 0.5);
    float roughness = clamp(uRoughness * (1.0 + uRoughnessVariation * 2.0 * (vLook.y - 0.5)), 0.02, 1.0);
    float occlusion = mix(1.0, exp(-3.0 * (1.0 - vLook.z)), uShadowDensity);
    // the container's cross-section for the other lights' density estimate (light.glsl), in a frame of
    // its axis: any frame will do, the estimate is round
    vec3 ez = vAxis.xyz;
    vec3 ex = normalize(abs(ez.x) < 0.9 ? cross(ez, vec3(1.0, 0.0, 0.0)) : cross(ez, vec3(0.0, 1.0, 0.0)));
    vec3 ey = cross(ez, ex);
    vec3 offset = vInside.xyz - dot(vInside.xyz, ez) * ez;
    ContainerShadow cs = ContainerShadow(transpose(mat3(ex, ey, ez)),
                                         vec2(dot(offset, ex), dot(offset, ey)) / max(vRadius, EPS_DIVISOR),
                                         SHADOW_MODE == 0 ? 0.0 : uShadowDensity * uFiberDensity);
    // shade the point of the round fiber's surface that this pixel sees, not the ribbon's axis
    float through = light_through(vFiberRadius * vRadius * N, uLightDir);
    vec3 shown = tone_map(shade_lights(T, Ns, V, color, roughness, occlusion, through, cs));
#if FILTER == 3
#if COMPOSITE == 0
    float weight = a * transmittance_before(k);
#else
    float weight = a * exp(-WEIGHT_FALLOFF * k);
#endif
    outValue = vec4(pow(shown, vec3(2.2)) * weight, weight);
    outDepth = vec4(sigma, 0.0, 0.0, 0.0);
#elif FILTER == 0
    outColor = vec4(shown, 1.0);
    outId = vId;
    outGeom = vec4(N, length(vPos));
#endif
}
