#version 450 core
// container.frag: the proxies strategy (renderer.py: VISIBILITY): per fragment of a container's proxy,
// rebuild the view ray, enter the container's unit space, traverse the virtual fibers and write the
// nearest hit (colour, ids, normal, true depth) or discard; the depth test keeps the nearest container's.
// Variants (defines): COST_PASS writes the work done (fiber tests, arcs, 1, loop iterations) for additive
// blending instead; SUPERSAMPLE n traces n x n stratified rays per pixel and writes coverage as alpha;
// MSAA_SAMPLES n traces one ray per sample and sets gl_SampleMask (colour only);
// SHADING_MODEL 0 Kajiya-Kay, 1 Marschner; SHADOW_MODE 0 off, 1 density estimate, 2 traced shadow ray.

#include "fibers/traverse.glsl"
#include "shading/fiber_shading.glsl"
#include "stages/view_ray.glsl"

flat in vec4 vSeg[7];       // the segment, packed by container.vert
flat in int vSegment;

uniform vec2 uSampleOffsets[16];    // sub-pixel offsets of the MSAA samples, in pixels

#ifndef COST_PASS
#define COST_PASS 0
#endif
#ifndef SUPERSAMPLE
#define SUPERSAMPLE 1
#endif
#ifndef MSAA_SAMPLES
#define MSAA_SAMPLES 0
#endif

#if COST_PASS
layout(location = 0) out vec4 outCost;
#else
layout(location = 0) out vec4 outColor;     // premultiplied by coverage
#if MSAA_SAMPLES == 0
layout(location = 1) out uvec4 outId;       // guide + 1, ring, fiber, segment
layout(location = 2) out vec4 outGeom;      // world normal, distance along the ray
#endif
#endif

// Depth of the hit, logarithmic in the distance so near 1e-4 and far 1e6 both resolve: 0 at uNear, 1 at
// the camera's far plane. One log2 per fragment: uDepthScale = 1 / log2(far / near), from the renderer.
uniform float uDepthScale;

float log_depth(float t) {
    return clamp(log2(max(t, uNear) / uNear) * uDepthScale, 0.0, 1.0);
}

Shaded trace_and_shade(Segment seg, vec3 rd, bool shade) {
    UnitRay ur;
    to_unit_space(seg, vec3(0.0), rd, uNear, ur);   // a miss leaves [s0, s1] empty: traverse finds nothing
    FiberHit hit = traverse(seg, ur);
    return shade_fiber_hit(seg, ur, hit, rd, uint(vSegment), shade);
}

void main() {
    Segment seg = unpack_segment(vSeg);
#if COST_PASS
    UnitRay ur;
    if (!to_unit_space(seg, vec3(0.0), view_ray(uPixelOffset), uNear, ur)) discard;
    FiberHit hit = traverse(seg, ur);
    outCost = vec4(float(gTests), float(gPieces), 1.0, float(gIters));
#elif MSAA_SAMPLES > 0
    // one ray per sample decides coverage; only the first sample that hits is shaded (MSAA's bargain:
    // coverage at every sample, colour once per pixel), the nearest hit sets the depth
    int mask = 0;
    Shaded best;
    best.hit = false;
    for (int k = 0; k < MSAA_SAMPLES; k++) {
        Shaded s = trace_and_shade(seg, view_ray(uPixelOffset + uSampleOffsets[k]), !best.hit);
        if (!s.hit) continue;
        mask |= 1 << k;
        if (!best.hit) best = s;
        best.t = min(best.t, s.t);
    }
    if (mask == 0) discard;
    gl_SampleMask[0] = mask & gl_SampleMaskIn[0];
    gl_FragDepth = log_depth(best.t);
    outColor = vec4(best.color, 1.0);
#elif SUPERSAMPLE == 1
    // One ray per pixel, written out without a loop: llvmpipe runs every statement inside a loop under
    // lane masks (a blend per assignment), even a loop of one pass.
    Shaded s = trace_and_shade(seg, view_ray(uPixelOffset), true);
    if (!s.hit) discard;
    gl_FragDepth = log_depth(s.t);
    outColor = vec4(s.color, 1.0);
    outId = s.id;
    outGeom = vec4(s.N, s.t);
#else
    // SUPERSAMPLE x SUPERSAMPLE stratified rays; the nearest hit names the pixel's fiber and depth
    vec3 sum = vec3(0.0);
    int hits = 0;
    Shaded nearest;
    nearest.hit = false;
    nearest.t = INF;
    for (int k = 0; k < SUPERSAMPLE * SUPERSAMPLE; k++) {
        vec2 cell = (vec2(k % SUPERSAMPLE, k / SUPERSAMPLE) + 0.5) / float(SUPERSAMPLE) - 0.5;
        Shaded s = trace_and_shade(seg, view_ray(uPixelOffset + cell), true);
        if (!s.hit) continue;
        hits++;
        sum += s.color;
        if (s.t < nearest.t) nearest = s;
    }
    if (hits == 0) discard;
    // the true depth of the fiber inside the container (logarithmic: near 1e-4 and far 1e6 both work)
    gl_FragDepth = log_depth(nearest.t);
    float coverage = float(hits) / float(SUPERSAMPLE * SUPERSAMPLE);
    outColor = vec4(sum / float(SUPERSAMPLE * SUPERSAMPLE), coverage);
    outId = nearest.id;
    outGeom = vec4(nearest.N, nearest.t);
#endif
}
