#version 450 core
// ribbon.frag: shade an explicit fiber's ribbon as the round fiber it stands for, with the virtual
// renderer's shading files and terms (stages/container.frag: trace_and_shade): the same per-fiber tint and
// roughness, sky occlusion by depth in the container, density self-shadow, shading model and tone map.
// SHADING_MODEL 0 Kajiya-Kay, 1 Marschner.

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

layout(location = 0) out vec4 outColor;
layout(location = 1) out uvec4 outId;       // guide + 1, ring, fiber, segment
layout(location = 2) out vec4 outGeom;      // world normal, distance along the ray

// Density self-shadow as the virtual renderer estimates it (stages/container.frag: light_transmittance):
// the fibers as a uniform medium along the light's path from the shaded point to the container's surface,
// in container radii. The path ends at the side wall (radius w about the segment's axis) or past the
// guide's root or tip; a joint between segments is no boundary for light (as there).
float light_through(vec3 P, vec3 L) {
#if SHADOW_MODE == 0
    return 1.0;
#else
    vec3 axis = vAxis.xyz;
    float z = vInside.w + dot(P, axis);
    vec3 offset = vInside.xyz + P - dot(P, axis) * axis;
    float along = dot(L, axis);
    vec3 Lp = L - along * axis;
    float w = vRadius;
    float a = dot(Lp, Lp);
    float b = dot(offset, Lp);
    float c = dot(offset, offset) - w * w;
    float side = a > 0.0 ? (-b + sqrt(max(0.0, b * b - a * c))) / a : 1e30;
    float end = 1e30;
    if (along > 0.0 && vEnds.y > 0.0) end = (vAxis.w - z) / along;
    if (along < 0.0 && vEnds.x > 0.0) end = -z / along;
    return exp(-uShadowDensity * uFiberDensity * max(0.0, min(side, end)) / max(w, EPS_DIVISOR));
#endif
}

void main() {
    vec3 V = normalize(-vPos);
    vec3 R = normalize(vTangent);
    // the round fiber's normal: sideways across the ribbon, toward the viewer in its middle
    vec3 S = normalize(cross(R, V));
    vec3 F = cross(S, R);
    float u = clamp(vAcross, -1.0, 1.0);
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
    vec3 L = uLightDir;
#if SHADING_MODEL == 1
    vec3 direct = shade_marschner(T, V, L, color, roughness);
#else
    vec3 direct = shade_kajiya_kay(T, Ns, V, L, color, roughness);
#endif
    // shade the point of the round fiber's surface that this pixel sees, not the ribbon's axis
    float through = light_through(vFiberRadius * vRadius * N, L);
    vec3 radiance = uLightIntensity * through * direct + ambient_fill(Ns, color, occlusion);
    outColor = vec4(tone_map(radiance), 1.0);
    outId = vId;
    outGeom = vec4(N, length(vPos));
}
