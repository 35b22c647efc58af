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
// another container appends itself to a list (`unfinished` counts it), and the renderer draws again
// (renderer.py: Renderer._walk_draws) over the list instead of the screen: fragment k of that draw walks
// listed pixel k. The pixels left after a draw are scattered, and a SIMD batch of 8 neighbouring pixels
// pays the whole batch for one of them; the list packs them 8 to a batch (harolongo: the draws after the
// first cost 2.2 us a pixel over the screen, ~0.6 listed). The first draw of a range runs over the screen
// where the coverage pass drew (the early depth test skips the rest).
// Variants (defines): TRAVERSAL 0 fast (the first container with a hit wins), 1 exact, 2 brute;
// COST_PASS also adds up the work of every draw in uCost and uWalk. FILTER 1 (quality.filter = coverage,
// exact only): each container also adds the share of the pixel's footprint its fibers cover, shaded as one
// blended fiber (fibers/coverage.glsl), under what the nearer containers left (uAccum, front to back in
// the walk's order: nearer bound first); bounds are grown by the footprint, and the walk goes on past the
// nearest fiber until the footprint is opaque. The nearest fiber (uState, uHitKey) is found as without.

layout(early_fragment_tests) in;

#include "common/epsilon.glsl"
#include "fibers/traverse.glsl"
#include "geometry/bvh.glsl"
#include "stages/view_ray.glsl"

#ifndef COST_PASS
#define COST_PASS 0
#endif
#ifndef FILTER
#define FILTER 0
#endif
#if FILTER
#include "fibers/coverage.glsl"
#include "shading/fiber_shading.glsl"
#endif
// The footprint's coverage at which the walk stops compositing past the nearest fiber (its bounds stop
// growing). The resolve shows the composite's colour over its alpha, so what the containers left would add
// is at most 1 - WALK_OPAQUE of a pixel's weight: at 0.97 sintel's and the far fur-ball's error and
// stability are unchanged (5.7 and 9.5 levels), their filtered frames 9% cheaper than at 0.999, where
// groom_auto's sparse-edged containers kept a pixel walking for a few more, each scanned and shaded; 0.95
// another 1.5% (stability within 0.1 point either way), 0.90 cost the far fur-ball 1.5 points of it.
#ifndef WALK_OPAQUE
#define WALK_OPAQUE 0.95
#endif

uniform int uRestart;           // 1: a new fiber range begins, walk from the nearest container again
uniform int uListed;            // 1: fragment k walks entry k of uListIn (of uListCount), 0: its own pixel
uniform int uListCount;
uniform int uListBlocks;        // 1: entries 8b..8b+7 are the 4x2 block b of a uListWidth-wide rectangle
uniform int uListWidth;

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
#if FILTER
layout(binding = 5, rgba32f) uniform coherent image2D uAccum;     // linear colour (premultiplied), alpha
layout(binding = 6, r32f) uniform coherent image2D uAccumFront;   // world t of the nearest colour so far
#endif
layout(std430, binding = 3) buffer Progress { uint unfinished; };
// the pixels still walking (x | y << 16), entry k at texel (k mod width, k / width): the list this draw
// walks and the one it appends to (renderer.py: LIST_UNITS)
layout(binding = 10, r32ui) uniform readonly uimage2D uListIn;
layout(binding = 11, r32ui) uniform writeonly uimage2D uListOut;

ivec2 list_texel(uint k, int width) {
    return ivec2(int(k % uint(width)), int(k / uint(width)));
}

// The pixel this fragment walks: its own, or in a listed draw the entry of its place in the rectangle,
// numbered so that a SIMD batch (a 4x2 block) takes 8 consecutive entries, which the draw before
// appended together from one batch of neighbouring pixels.
ivec2 walked_pixel(out bool valid) {
    ivec2 f = ivec2(gl_FragCoord.xy);
    int k = uListBlocks != 0
        ? (((f.y >> 1) * (uListWidth >> 2) + (f.x >> 2)) << 3) | ((f.y & 1) << 2) | (f.x & 3)
        : f.y * uListWidth + f.x;
    valid = uListed == 0 || k < uListCount;
    uint e = imageLoad(uListIn, list_texel(uint(min(k, max(uListCount - 1, 0))), imageSize(uListIn).x)).x;
    return uListed != 0 ? ivec2(int(e & 0xFFFFu), int(e >> 16)) : f;
}

// A container whose box the ray enters after bestT cannot hold a nearer fiber; the margin covers the
// float32 rounding between the box entry and the container entry computed in unit space.
float walk_cut(float bestT) {
    return bestT < INF ? bestT * (1.0 + EPS_WALK_CUT) : INF;
}

// v itself, through an operation the compiler cannot see through (bit 30 of a window coordinate is 0):
// a uniform the walk's loop reads directly is re-read inside the loop, and llvmpipe reads it there as a
// per-lane gather at every step (perf: two a step, ~4% of the loop)
int opaque(int v) {
    return v | (int(gl_FragCoord.y) & 0x40000000);
}
float opaque(float v) {
    return uintBitsToFloat(floatBitsToUint(v) | (uint(gl_FragCoord.y) & 0x40000000u));
}
vec3 opaque(vec3 v) {
    return vec3(opaque(v.x), opaque(v.y), opaque(v.z));
}

void main() {
    bool valid;
    ivec2 px = walked_pixel(valid);
    if (!valid) discard;        // past the list's end: a discarded fragment stores nothing
    uvec4 state = imageLoad(uState, px);
    float bestT = state.x == 0u ? INF : uintBitsToFloat(state.x);
    uint bestSeg = state.y;
    uint node = uRestart != 0 ? 0u : state.z;
    uint trail = uRestart != 0 ? 0u : state.w;
    vec3 rd = view_ray_at(vec2(px) + 0.5, uPixelOffset);
    vec3 shift = opaque(uSceneFromCamera);
    DopRay ray = dop_ray(rd, shift);
    int depth = opaque(uBvhDepth);
    float tNear = opaque(uNear);
#if FILTER
    vec4 accum = imageLoad(uAccum, px);
    // until the footprint is opaque every container it meets adds colour, behind the nearest fiber too, and
    // the walk's bounds are grown by it; once it is, the walk looks for the nearest fiber only, as without
    bool opaque = accum.a >= WALK_OPAQUE;
    gBoundGrow = opaque ? 0.0 : uFootprint;
    float cut = opaque ? walk_cut(bestT) : INF;
#else
    float cut = walk_cut(bestT);
#endif

    // on to the next container (a pixel that stopped at one last draw stands on it already)
    walk_to_leaf(node, trail, rd, ray, shift, depth, tNear, cut);
    bool visit = node != WALK_DONE && node_level(node) == depth;
    // no branch around the traversal: under a lane mask llvmpipe pays a blend for every assignment in it,
    // so a pixel with nothing to visit traverses segment 0 along an empty interval instead
    uint id = leaf_segment(visit ? int(node) - (uBvhLeaves - 1) : 0);
    Segment seg = fetch_segment(id);
    UnitRay ur;
    bool inside = to_unit_space(seg, vec3(0.0), rd, uNear, ur) && visit;
    ur.s0 = inside ? ur.s0 : INF;
    ur.s1 = inside ? ur.s1 : -INF;
    int entered = inside ? 1 : 0;
    limit_traversal(seg, ur, bestT);        // the walk's nearest so far: only a nearer fiber matters here
    FiberHit best = traverse(seg, ur);
    float t = best.s < INF ? unit_to_world_t(seg, ur, best.s) : INF;
    bool improved = best.s < INF && key_before(t, id, bestT, bestSeg);
    bestT = improved ? t : bestT;
    bestSeg = improved ? id : bestSeg;
#if FILTER
    UnitRay uf;
    float wu;
    bool near = to_unit_space_dilated(seg, rd, uNear, uf, wu) && visit;
    // once the footprint is opaque the walk goes on only for a nearer fiber; a container it then enters
    // behind the composite's front could only go under it, at most 1 - WALK_OPAQUE of its weight: not scanned
    float front = accum.a > 0.0 ? imageLoad(uAccumFront, px).x : INF;
    near = near && !(opaque && uf.tb >= front);
    uf.s0 = near ? uf.s0 : INF;
    uf.s1 = near ? uf.s1 : -INF;
    // the key light and the self-shadow estimate per fiber (traced shadows: a shadow ray, below)
    vec3 Lu = transpose(mat3(seg.ex, seg.ey, seg.ez)) * uLightDir;
    float sigma = SHADOW_MODE == 1 ? uShadowDensity * uFiberDensity : 0.0;
    CoverBlend cb = cover_container(seg, uf, wu, Lu, vec2(sigma, uShadowDensity));
    gTests += cb.tests;
#if !COST_PASS
    FiberHit bh = no_hit();
    bh.s = cb.s;
    bh.ring = 0;
    bh.fiber = 0;
    bh.c = cb.c;
    vec3 P = vec3(cb.c + cb.radial, uf.O.z + cb.s * uf.D.z);
    vec4 given = vec4(cb.tint, cb.rough, cb.light, cb.occlusion);
#if SHADOW_MODE == 2
    // Traced shadows: the blend is no one fiber, and its point (the mean centre, on the ring) lies inside
    // the ring's fibers where they overlap (harolongo: 6.8 widths), so a ray from it met its own ring at
    // once: nearly every blended pixel was shadowed (34.2 levels, 32 too dark; skipping no fiber instead of
    // ring 0's first changed nothing). The ray is the unfiltered frame's: from the container's nearest fiber
    // on the pixel's centre ray, where rays first meet the fibers, skipping that fiber; where that ray meets
    // none nearer than the walk's best, lit (docs/antialias.md: a second traversal to find one there cost
    // 12-16% of the frame for 0.1 levels).
    vec3 Pe = ur.O + best.s * ur.D;
    given.z = best.s < INF ? light_transmittance(seg, ur, best, Pe, uLightDir) : 1.0;
#endif
    Shaded sh = shade_fiber_at(seg, uf, bh, P, given, rd, id, true);
    // composited in linear light (the reference averages there). The walk is depth first, nearer child
    // first: containers come roughly, not exactly, front to back, so each goes over what is there when it
    // starts nearer than all of it, else under (exact for two layers in either order).
    float tc = unit_to_world_t(seg, uf, cb.s);
    vec4 mine = vec4(cb.alpha * sh.linear, cb.alpha);
    bool over = tc < front;
    accum = cb.alpha > 0.0 ? (over ? mine + (1.0 - cb.alpha) * accum : accum + (1.0 - accum.a) * mine) : accum;
    imageStore(uAccum, px, accum);
    imageStore(uAccumFront, px, vec4(cb.alpha > 0.0 ? min(front, tc) : front));
#endif
    opaque = accum.a >= WALK_OPAQUE;
    gBoundGrow = opaque ? 0.0 : uFootprint;
    cut = opaque ? walk_cut(bestT) : INF;
#else
    cut = walk_cut(bestT);
#endif
    // past this container, and on to the next one now, so a pixel with none left is done at once
    uint upNode = node;
    uint upTrail = trail;
    pop(upNode, upTrail);
    node = visit ? upNode : node;
    trail = visit ? upTrail : trail;
    walk_to_leaf(node, trail, rd, ray, shift, depth, tNear, cut);
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
    if (!finished) {
        uint slot = atomicAdd(unfinished, 1u);
        imageStore(uListOut, list_texel(slot, imageSize(uListOut).x), uvec4(uint(px.x) | (uint(px.y) << 16)));
    }
}
