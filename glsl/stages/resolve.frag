#version 450 core
// resolve.frag: shade each pixel's nearest fiber, which the walk passes (walk.frag) found and kept in
// the state images: colour, ids, normal and distance. Pixels without a hit discard (background).
// FILTER 1: the colour is what the walk composited from the footprint's coverage (uAccum, linear); ids,
// normal and distance stay the nearest fiber's, and a pixel the footprint covers without a hit at its
// centre gets colour with no ids.

layout(early_fragment_tests) in;

#include "fibers/traverse.glsl"
#include "geometry/bvh.glsl"
#include "shading/fiber_shading.glsl"
#include "stages/view_ray.glsl"

layout(binding = 0, rgba32ui) uniform readonly uimage2D uState;
layout(binding = 1, rgba32ui) uniform readonly uimage2D uHitKey;
layout(binding = 2, rgba32f) uniform readonly image2D uHitShape;
#ifndef FILTER
#define FILTER 0
#endif
#if FILTER
layout(binding = 5, rgba32f) uniform readonly image2D uAccum;
#endif

layout(location = 0) out vec4 outColor;     // premultiplied by coverage
layout(location = 1) out uvec4 outId;       // guide + 1, ring, fiber, segment
layout(location = 2) out vec4 outGeom;      // world normal, distance along the ray

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    uvec4 state = imageLoad(uState, px);
#if FILTER
    vec4 accum = imageLoad(uAccum, px);
    if (state.x == 0u && !(accum.a > 0.0)) discard;
#else
    if (state.x == 0u) discard;
#endif
    uvec4 key = imageLoad(uHitKey, px);
    vec4 shape = imageLoad(uHitShape, px);
    FiberHit hit;
    hit.ring = int(key.x);
    hit.fiber = int(key.y);
    hit.kind = int(key.z);
    hit.s = uintBitsToFloat(key.w);
    hit.c = shape.xy;
    hit.dcdv = shape.zw;
    vec3 rd = view_ray(uPixelOffset);
    // the winner's unit-space ray, recomputed: the same numbers the walk traversed with
    Segment seg = fetch_segment(state.y);
    UnitRay ur;
    to_unit_space(seg, vec3(0.0), rd, uNear, ur);
#if FILTER
    Shaded s = shade_fiber_hit(seg, ur, hit, rd, state.y, false);
    bool found = state.x != 0u;
    float a = clamp(accum.a, 0.0, 1.0);
    vec3 shown = a > 0.0 ? pow(clamp(accum.rgb / a, 0.0, 1.0), vec3(1.0 / 2.2)) : vec3(0.0);
    outColor = vec4(shown * a, a);          // premultiplied in display levels, as the unfiltered frame
    outId = found ? s.id : uvec4(0u);
    outGeom = found ? vec4(s.N, s.t) : vec4(0.0);
#else
    Shaded s = shade_fiber_hit(seg, ur, hit, rd, state.y, true);
    outColor = vec4(s.color, 1.0);
    outId = s.id;
    outGeom = vec4(s.N, s.t);
#endif
}
