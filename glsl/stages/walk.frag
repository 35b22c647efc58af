#version 450 core
// walk.frag: per pixel, the nearest fiber over every container the view ray enters. The walk
// (geometry/bvh.glsl) goes through the container hierarchy nearer child first and hands over each
// container whose bounding cylinder the ray enters before the nearest fiber found so far; each is
// traversed (fibers/traverse.glsl), so a pixel pays for the containers in front of its fiber, not for
// every container that overlaps it on screen.
// The pass writes no colour: it keeps each pixel's best hit and its place in the walk in images
// (uState, uHit*), and resolve.frag shades the winner once. One draw traverses one container per pixel,
// like a proxy fragment did: llvmpipe runs a loop as long as its slowest lane, so a loop over several
// containers would make each SIMD batch pay for its deepest pixel at every step. A pixel that needs
// another container counts itself in `unfinished`, and the renderer draws again
// (renderer.py: Renderer._walk_draws); mark_done.frag then writes depth where a pixel is done, and the
// early depth test keeps it out of later draws (the rasterizer, not this shader, skips it).
// Variants (defines): TRAVERSAL 0 fast (the first container with a hit wins), 1 exact, 2 brute;
// COST_PASS also adds up the work of every draw in uCost and uWalk.

layout(early_fragment_tests) in;

#include "common/epsilon.glsl"
#include "fibers/traverse.glsl"
#include "geometry/bvh.glsl"
#include "stages/view_ray.glsl"

#ifndef COST_PASS
#define COST_PASS 0
#endif

uniform int uRestart;           // 1: a new fiber range begins, walk from the nearest container again

// x: best hit t (bits; 0: none yet), y: its scene segment, z, w: the pixel's place in the walk (node,
// trail: bvh.glsl; node WALK_DONE: this pixel is done). All zero is a fresh pixel at the root, so the
// renderer clears the state with a plain clear: every t here is at least uNear > 0.
layout(binding = 0, rgba32ui) uniform coherent uimage2D uState;
layout(binding = 1, rgba32ui) uniform coherent uimage2D uHitKey;   // ring, fiber, kind, s bits
layout(binding = 2, rgba32f) uniform coherent image2D uHitShape;   // fiber centre c.xy, dc/dv.xy
#if COST_PASS
layout(binding = 3, rgba32f) uniform coherent image2D uCost;       // fiber tests, arcs, containers entered, loop passes
layout(binding = 4, rgba32f) uniform coherent image2D uWalk;       // candidates traversed, box tests, walks, walks run out
#endif
layout(std430, binding = 3) buffer Progress { uint unfinished; };

// A container whose box the ray enters after bestT cannot hold a nearer fiber; the margin covers the
// float32 rounding between the box entry and the container entry computed in unit space.
float walk_cut(float bestT) {
    return bestT < INF ? bestT * (1.0 + EPS_WALK_CUT) : INF;
}

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    uvec4 state = imageLoad(uState, px);
    float bestT = state.x == 0u ? INF : uintBitsToFloat(state.x);
    uint bestSeg = state.y;
    uint node = uRestart != 0 ? 0u : state.z;
    uint trail = uRestart != 0 ? 0u : state.w;
    vec3 rd = view_ray(uPixelOffset);

    // on to the next container (a pixel that stopped at one last draw stands on it already)
    walk_to_leaf(node, trail, rd, uNear, walk_cut(bestT));
    bool visit = node != WALK_DONE && node_level(node) == uBvhDepth;
    // no branch around the traversal: under a lane mask llvmpipe pays a blend for every assignment in it,
    // so a pixel with nothing to visit traverses segment 0 along an empty interval instead
    uint id = bvhOrder[visit ? int(node) - (uBvhLeaves - 1) : 0];
    Segment seg = fetch_segment(id);
    UnitRay ur;
    bool inside = to_unit_space(seg, vec3(0.0), rd, uNear, ur) && visit;
    ur.s0 = inside ? ur.s0 : INF;
    ur.s1 = inside ? ur.s1 : -INF;
    int entered = inside ? 1 : 0;
    FiberHit best = traverse(seg, ur);
    float t = best.s < INF ? unit_to_world_t(seg, ur, best.s) : INF;
    bool improved = best.s < INF && key_before(t, id, bestT, bestSeg);
    bestT = improved ? t : bestT;
    bestSeg = improved ? id : bestSeg;
    // past this container, and on to the next one now, so a pixel with none left is done at once
    uint upNode = node;
    uint upTrail = trail;
    pop(upNode, upTrail);
    node = visit ? upNode : node;
    trail = visit ? upTrail : trail;
    walk_to_leaf(node, trail, rd, uNear, walk_cut(bestT));
    node = (gMode == 0 && bestT < INF) ? WALK_DONE : node;     // fast: the first container with a hit wins
    bool finished = node == WALK_DONE;
    imageStore(uState, px, uvec4(bestT < INF ? floatBitsToUint(bestT) : 0u, bestSeg, node, trail));
    if (improved) {
        imageStore(uHitKey, px, uvec4(uint(best.ring), uint(best.fiber), uint(best.kind), floatBitsToUint(best.s)));
        imageStore(uHitShape, px, vec4(best.c, best.dcdv));
    }
#if COST_PASS
    loop_canary();
    gIters = gWalkRanOut ? max(gIters, LOOP_CAP) : gIters;
    imageStore(uCost, px, imageLoad(uCost, px)
               + vec4(float(gTests), float(gPieces), float(entered), float(gIters + gWalkSteps)));
    imageStore(uWalk, px, imageLoad(uWalk, px)
               + vec4(visit ? 1.0 : 0.0, float(gWalkSteps), 1.0, 0.0));
#endif
    if (!finished) atomicAdd(unfinished, 1u);
}
