// strands.glsl: explicit fiber polylines, pulled from storage buffers (the conventional baseline).
//   Strand strand_at(int fiber, int k)        vertex k of a fiber of the chunk bound at 0/1, scene-relative
//   uint   strand_record(int fiber)           tint (8 bits), roughness (8 bits), last vertex k_end (16 bits)
// Storage (app/render/explicit.py writes it, and says why this format):
//   vertex = half4(d.xyz, t): P = mix(J_s, J_s+1, t) + mix(r_s, r_s+1, t) * d, s = the vertex's segment
//   (vertex 0 lies in segment 0, vertex k >= 1 in segment k - 1), J/r = the chain's joints and radii.
// Twin: app/render/explicit.py (chain_strands).

#ifndef EXPLICIT_STRANDS_GLSL
#define EXPLICIT_STRANDS_GLSL

layout(std430, binding = 0) readonly buffer StrandVertices { uvec2 strandVertex[]; };
layout(std430, binding = 1) readonly buffer StrandRecords { uint strandRecord[]; };
layout(std430, binding = 2) readonly buffer Joints { vec4 joint[]; };       // xyz scene-relative, w radius
layout(std430, binding = 3) readonly buffer Chains { uvec4 chain[]; };      // joint0, row0, guide, segments

uniform int uSegments;          // S: segments of every chain in the group being drawn

struct Strand {
    vec3 p;                     // scene-relative position
    float w;                    // container radius there (the fiber's radius is uFiberRadius * w)
    float c;                    // |c|: distance of the fiber from the container axis, unit space
};

uint strand_record(int fiber) {
    return strandRecord[fiber];
}

Strand strand_at(int fiber, int k, uint joint0) {
    uvec2 bits = strandVertex[fiber * (uSegments + 1) + k];
    vec2 dxy = unpackHalf2x16(bits.x);
    vec2 dzt = unpackHalf2x16(bits.y);
    vec3 d = vec3(dxy, dzt.x);
    uint s = uint(max(k, 1) - 1);
    vec4 j0 = joint[joint0 + s];
    vec4 j1 = joint[joint0 + s + 1u];
    Strand st;
    st.w = mix(j0.w, j1.w, dzt.y);
    st.p = mix(j0.xyz, j1.xyz, dzt.y) + st.w * d;
    st.c = length(d);
    return st;
}

#endif
