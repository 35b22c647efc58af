#version 450 core
// ribbon.frag: shade an explicit fiber's ribbon as the round fiber it stands for, with the virtual
// renderer's shading (shading/hair.glsl) and the same per-fiber tint, roughness and density shadow.

#include "shading/hair.glsl"

in vec3 vPos;
in vec3 vTangent;
in float vAcross;
flat in uvec4 vId;
flat in vec3 vLook;

uniform vec3 uBaseColor;
uniform float uRoughness;
uniform float uTintVariation;
uniform float uRoughnessVariation;
uniform float uShadowDensity;
uniform float uFiberRadius;

layout(location = 0) out vec4 outColor;
layout(location = 1) out uvec4 outId;       // guide + 1, ring, fiber, segment
layout(location = 2) out vec4 outGeom;      // world normal, distance along the ray

void main() {
    vec3 V = normalize(-vPos);
    vec3 T = normalize(vTangent);
    // the round fiber's normal: sideways across the ribbon, toward the viewer in its middle
    vec3 S = normalize(cross(T, V));
    vec3 F = cross(S, T);
    float u = clamp(vAcross, -1.0, 1.0);
    float facing = sqrt(max(0.0, 1.0 - u * u));
    vec3 N = normalize(S * u + F * facing);

    float tint = vLook.x - 0.5;
    float rough = vLook.y - 0.5;
    vec3 albedo = clamp(uBaseColor * (1.0 + uTintVariation * 2.0 * tint), 0.0, 1.0);
    float roughness = clamp(uRoughness * (1.0 + uRoughnessVariation * 2.0 * rough), 0.02, 1.0);
    float depthIn = 1.0 - vLook.z;
    float occlusion = mix(1.0, exp(-3.0 * depthIn), uShadowDensity);

    outColor = vec4(tone_map(shade_fiber(T, N, V, albedo, roughness, occlusion)), 1.0);
    outId = vId;
    outGeom = vec4(N, length(vPos));
}
