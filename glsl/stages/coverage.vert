#version 450 core
// coverage.vert: the pixels any container can cover, cheaply: the screen rectangle around one node box
// of the container hierarchy (app/render/bvh.py) at a coarse level, per instance, at depth 0. The walk
// passes (walk.frag) then run only where this drew: llvmpipe runs every loop body of a shader at least
// once per SIMD batch, so a fullscreen pass would pay a traversal's code on every background pixel.
// A box with a corner at or behind the camera plane covers the whole viewport (the camera is in or
// beside it); an empty box covers nothing.

#include "geometry/bvh.glsl"

uniform mat4 uClipFromCamera;   // projection * view rotation (camera at the origin)
uniform vec2 uViewport;
uniform int uCoverageFirst;     // index of the first node of the level drawn
uniform float uGrowPx;          // the filtered mode's footprint half-width in pixels (0 without)

void main() {
    int node = uCoverageFirst + gl_InstanceID;
    vec3 lo, hi;
    node_box(node, lo, hi);
    bool empty = !(lo.x <= hi.x);
    lo += uSceneFromCamera;
    hi += uSceneFromCamera;
    vec2 corner = vec2(float(gl_VertexID == 1 || gl_VertexID == 2 || gl_VertexID == 4),
                       float(gl_VertexID == 2 || gl_VertexID == 4 || gl_VertexID == 5));
    vec2 pLo = vec2(3e38);
    vec2 pHi = vec2(-3e38);
    bool behind = false;
    for (int k = 0; k < 8; k++) {
        vec3 c = vec3((k & 1) != 0 ? hi.x : lo.x, (k & 2) != 0 ? hi.y : lo.y, (k & 4) != 0 ? hi.z : lo.z);
        vec4 clip = uClipFromCamera * vec4(c, 1.0);
        behind = behind || !(clip.w > EPS_CLIP_W * length(clip.xyz));
        vec2 ndc = clip.xy / clip.w;
        pLo = min(pLo, ndc);
        pHi = max(pHi, ndc);
    }
    // two pixels of margin: sub-pixel sample offsets reach half a pixel past the centre (and the filtered
    // mode's footprint its half-width)
    vec2 margin = (4.0 + 2.0 * uGrowPx) / uViewport;
    vec2 ndc = behind ? corner * 2.0 - 1.0 : mix(pLo - margin, pHi + margin, corner);
    ndc = empty ? vec2(-2.0) : clamp(ndc, -1.0, 1.0);
    gl_Position = vec4(ndc, -1.0, 1.0);
}
