#version 450 core
// resolve.frag: shade each pixel's nearest fiber, which the walk passes (walk.frag) found and kept in
// the state images: colour, ids, normal and distance. Pixels without a hit discard (background).

layout(early_fragment_tests) in;

#include "fibers/traverse.glsl"
#include "geometry/bvh.glsl"
#include "shading/fiber_shading.glsl"
#include "stages/view_ray.glsl"

layout(binding = 0, rgba32ui) uniform readonly uimage2D uState;
layout(binding = 1, rgba32ui) uniform readonly uimage2D uHitKey;
layout(binding = 2, rgba32f) uniform readonly image2D uHitShape;

layout(location = 0) out vec4 outColor;     // premultiplied by coverage
layout(location = 1) out uvec4 outId;       // guide + 1, ring, fiber, segment
layout(location = 2) out vec4 outGeom;      // world normal, distance along the ray

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    uvec4 state = imageLoad(uState, px);
    if (state.x == 0u) discard;
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
    Shaded s = shade_fiber_hit(seg, ur, hit, rd, state.y, true);
    outColor = vec4(s.color, 1.0);
    outId = s.id;
    outGeom = vec4(s.N, s.t);
}
