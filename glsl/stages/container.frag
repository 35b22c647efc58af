#version 450 core
// container.frag: the proxies strategy (renderer.py: VISIBILITY): per fragment of a container's proxy,
// rebuild the view ray, enter the container's unit space, traverse the virtual fibers and write the
// nearest hit (colour, ids, normal, true depth) or discard; the depth test keeps the nearest container's.
// Variants (defines): COST_PASS writes the work done (fiber tests, arcs, 1, loop iterations) for additive
// blending instead; SHADING_MODEL 0 Kajiya-Kay, 1 Marschner; SHADOW_MODE 0 off, 1 density estimate, 2 traced
// shadow ray. One ray per pixel: antialiasing draws a whole frame per sample (renderer.py: render), since a
// fragment sees only its own container and the depth test keeps one fragment per pixel, so rays traced here
// at sub-pixel offsets could not reach the container behind where they miss this one's fibers.

#include "fibers/traverse.glsl"
#include "shading/fiber_shading.glsl"
#include "stages/view_ray.glsl"

flat in vec4 vSeg[7];       // the segment, packed by container.vert
flat in int vSegment;

#ifndef COST_PASS
#define COST_PASS 0
#endif

#if COST_PASS
layout(location = 0) out vec4 outCost;
#else
layout(location = 0) out vec4 outColor;     // premultiplied by coverage
layout(location = 1) out uvec4 outId;       // guide + 1, ring, fiber, segment
layout(location = 2) out vec4 outGeom;      // world normal, distance along the ray
#endif

// The nearest hit so far at each pixel, from the proxies drawn before this one (the renderer draws them
// nearest first and clears this per pass): a traversal need not look past it (limit_traversal), so a
// proxy behind a nearer container's fiber costs its entry, and at a joint the second segment its stretch
// before the hit. Stored as 0xffffffff - the float's bits, so that a cleared 0 is "none" and the nearest
// is the largest: positive floats order as their bits. Another fragment of the same draw may write it
// between this one's read and write: then the bound read is only looser, and the depth test still keeps
// the nearest.
layout(r32ui, binding = 12) uniform coherent uimage2D uNearestHit;     // renderer.py: NEAREST_UNIT

float nearest_so_far() {
    uint stored = imageLoad(uNearestHit, ivec2(gl_FragCoord.xy)).x;
    return stored == 0u ? INF : uintBitsToFloat(0xffffffffu - stored);
}

void report_hit(float t) {
    imageAtomicMax(uNearestHit, ivec2(gl_FragCoord.xy), 0xffffffffu - floatBitsToUint(max(t, 0.0)));
}

// Depth of the hit, logarithmic in the distance so near 1e-4 and far 1e6 both resolve: 0 at uNear, 1 at
// the camera's far plane. One log2 per fragment: uDepthScale = 1 / log2(far / near), from the renderer.
uniform float uDepthScale;

float log_depth(float t) {
    return clamp(log2(max(t, uNear) / uNear) * uDepthScale, 0.0, 1.0);
}

Shaded trace_and_shade(Segment seg, vec3 rd, bool shade) {
    UnitRay ur;
    to_unit_space(seg, vec3(0.0), rd, uNear, ur);   // a miss leaves [s0, s1] empty: traverse finds nothing
    limit_traversal(seg, ur, nearest_so_far());
    FiberHit hit = traverse(seg, ur);
    return shade_fiber_hit(seg, ur, hit, rd, uint(vSegment), shade);
}

void main() {
    Segment seg = unpack_segment(vSeg);
#if COST_PASS
    UnitRay ur;
    if (!to_unit_space(seg, vec3(0.0), view_ray(uPixelOffset), uNear, ur)) discard;
    limit_traversal(seg, ur, nearest_so_far());
    FiberHit hit = traverse(seg, ur);
    if (hit.s < INF) report_hit(unit_to_world_t(seg, ur, hit.s));
    outCost = vec4(float(gTests), float(gPieces), 1.0, float(gIters));
#else
    // One ray per pixel, written out without a loop: llvmpipe runs every statement inside a loop under
    // lane masks (a blend per assignment), even a loop of one pass.
    Shaded s = trace_and_shade(seg, view_ray(uPixelOffset), true);
    if (!s.hit) discard;
    report_hit(s.t);
    gl_FragDepth = log_depth(s.t);
    outColor = vec4(s.color, 1.0);
    outId = s.id;
    outGeom = vec4(s.N, s.t);
#endif
}
