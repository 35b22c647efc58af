// bvh.glsl: the containers a ray enters, nearest first, from the hierarchy of app/render/bvh.py.
//   uvec4     record_word(int k)                                         word k of the hierarchy (four a record)
//   uint      leaf_segment(int leaf)                                     scene index of a leaf's segment
//   Segment   fetch_segment(uint index)                                  scene segment, camera-relative
//   void      node_box(int node, out vec3 lo, out vec3 hi)               a node's box, scene-relative (lo > hi: empty)
//   DopRay    dop_ray(vec3 rd, vec3 shift)                               the ray against the DOP grids
//   void      walk_to_leaf(inout uint node, inout uint trail, vec3 rd, DopRay ray, vec3 shift, int depth,
//                          float tNear, float tCut)
//   void      pop(inout uint node, inout uint trail)
//   bool      key_before(float ta, uint ia, float tb, uint ib)
// The tree is implicit and complete: node i has children 2i + 1 and 2i + 2, and leaf j (node
// uBvhLeaves - 1 + j) holds sorted segment j, so every step of the walk is the same two bound tests and
// the loop body stays short (llvmpipe runs every branch of a loop body for the whole SIMD batch, and
// every image read is a gather over its lanes). Inner nodes are bounded by 14-DOPs (slabs along the
// axes and the four body diagonals, dop_along_a/b), leaves by their container's bounding cylinder; a step
// reads its node's record (record node + 1: both children's bounds, four words) and tests both children.
// The walk keeps no stack: bit l of `trail` says the far child of the level-l node on the current path
// is still to visit, and the node to resume at follows from the current node's index (heap arithmetic),
// so a pixel's whole place in the walk is two integers: it can stop after any leaf and go on in the next
// draw (walk.frag). A bound the ray enters after the nearest fiber found so far holds no nearer one.
// The scene's words (hierarchy records, leaf order, segments) are read from images, WORD_ROW texels a row
// (renderer.py: WORD_ROW), not from storage buffers: llvmpipe reads a storage buffer at a per-lane index one
// lane and one component at a time (a loop that stalls on every component, ~300 ns a vec4 per 8-lane batch),
// an image with one gather per batch (~60 ns); harolongo's frame took 2.7x less CPU (docs/performance.md).
// Twin: app/render/bvh.py (segment_cylinders, cylinder_dops, the records; decoded_bounds);
// tests/render/test_bvh.py walks the same tree in numpy.

#ifndef GEOMETRY_BVH_GLSL
#define GEOMETRY_BVH_GLSL

#include "common/epsilon.glsl"
#include "geometry/container.glsl"

#ifndef WALK_CAP
#define WALK_CAP 4096       // walk steps per call; one that runs out is reported (walk.frag, cost output)
#endif

#define WORD_ROW_SHIFT 12        // renderer.py: WORD_ROW = 1 << WORD_ROW_SHIFT texels a row
layout(binding = 7, rgba32ui) uniform readonly uimage2D uBvhRecords;   // four words per record
layout(binding = 8, r32ui) uniform readonly uimage2D uBvhOrder;         // scene index per leaf
layout(binding = 9, rgba32f) uniform readonly image2D uSegmentWords;    // five words per scene segment

uniform int uBvhLeaves;         // leaves: a power of two
uniform int uBvhDepth;          // log2(uBvhLeaves)
uniform int uSegmentCount;
uniform vec3 uSceneFromCamera;  // scene origin minus camera position: the tree and segments are scene-relative
// A DOP bound q (16 bits) along direction k is base[k] + q * step[k]; directions 0-3 in the A vectors,
// 4-6 in the B ones (vectors, not arrays: llvmpipe gathered indexed uniforms lane by lane in the loop).
uniform vec4 uDopBaseA;
uniform vec3 uDopBaseB;
uniform vec4 uDopStepA;
uniform vec3 uDopStepB;

// bvh.py: DOP_DIRECTIONS, the axes and the four body diagonals (1, +-1, +-1) / sqrt(3), in that order
const float DOP_D = 0.57735026918962576;
vec4 dop_along_a(vec3 v) {
    return vec4(v, DOP_D * (v.x + v.y + v.z));
}
vec3 dop_along_b(vec3 v) {
    return DOP_D * vec3(v.x - v.y + v.z, v.x + v.y - v.z, v.x - v.y - v.z);
}

const uint WALK_DONE = 0xFFFFFFFFu;
// The filtered mode's footprint half-width per unit distance (walk.frag sets it): every bound grows by the
// footprint at its farthest point, so a container a pixel's footprint reaches is walked into.
float gBoundGrow = 0.0;
int gWalkSteps = 0;             // walk steps (two bound tests each), all walks of this invocation
bool gWalkRanOut = false;

ivec2 word_texel(int k) {
    return ivec2(k & ((1 << WORD_ROW_SHIFT) - 1), k >> WORD_ROW_SHIFT);
}

uvec4 record_word(int k) {
    return imageLoad(uBvhRecords, word_texel(k));
}

uint leaf_segment(int leaf) {
    return imageLoad(uBvhOrder, word_texel(leaf)).x;
}

vec4 segment_word(int k) {
    return imageLoad(uSegmentWords, word_texel(k));
}

// The container segment as container.glsl builds it from the renderer's five vec4 per segment.
Segment fetch_segment(uint index) {
    int k = int(index) * 5;
    vec4 a = segment_word(k);
    vec4 b = segment_word(k + 1);
    return make_segment(vec4(a.xyz + uSceneFromCamera, a.w), vec4(b.xyz + uSceneFromCamera, b.w),
                        segment_word(k + 2), segment_word(k + 3), segment_word(k + 4));
}

// Key order for hits in different containers: distance, then scene index (the lower index wins a tie
// in every mode).
bool key_before(float ta, uint ia, float tb, uint ib) {
    return ta < tb || (ta == tb && ia < ib);
}

// A ray against the DOP grids: along direction k, a bound q lies at t = q * a[k] + b[k] (its position
// and reciprocal direction along each of the seven directions, taken once per walk: inside the loop a
// slab then costs what a box axis costs). inv: the reciprocal directions (the filtered mode's growth).
struct DopRay {
    vec4 a0;
    vec3 a1;
    vec4 b0;
    vec3 b1;
    vec4 i0;
    vec3 i1;
    uvec4 s0;       // 16 where the ray runs backwards along the direction (a < 0), else 0
    uvec3 s1;
};

vec4 dop_reciprocal(vec4 d) {
    // a zero component gives a large finite reciprocal: the slab then compares as a slab, with no NaN
    return 1.0 / mix(max(d, vec4(EPS_DIVISOR)), min(d, vec4(-EPS_DIVISOR)), lessThan(d, vec4(0.0)));
}

DopRay dop_ray(vec3 rd, vec3 shift) {
    DopRay r;
    vec4 inv0 = dop_reciprocal(dop_along_a(rd));
    vec3 inv1 = dop_reciprocal(vec4(dop_along_b(rd), 1.0)).xyz;
    // the camera sits at -shift in the tree's (scene-relative) frame
    r.a0 = uDopStepA * inv0;
    r.a1 = uDopStepB * inv1;
    r.b0 = (uDopBaseA + dop_along_a(shift)) * inv0;
    r.b1 = (uDopBaseB + dop_along_b(shift)) * inv1;
    r.i0 = inv0;
    r.i1 = inv1;
    r.s0 = mix(uvec4(0u), uvec4(16u), lessThan(inv0, vec4(0.0)));
    r.s1 = mix(uvec3(0u), uvec3(16u), lessThan(inv1, vec3(0.0)));
    return r;
}

// Entry and exit t of the ray through a DOP (u0: directions 0-3, u1: 4-6, each q_lo | q_hi << 16); an
// empty node (bvh.py: q_lo = 65535, q_hi = 0) gives entry > exit. Along a direction the ray runs backwards on (a < 0), the
// near bound is q_hi: the two halves of the word are swapped (r.s: 16 there, else 0) instead of sorting
// the two t by min and max, which llvmpipe makes NaN-safe at three instructions each.
vec2 dop_interval(uvec4 u0, uvec3 u1, DopRay r) {
#if defined(FILTER) && FILTER
    bool empty = (u0.x & 0xFFFFu) > (u0.x >> 16u);
#endif
    u0 = (u0 >> r.s0) | (u0 << ((32u - r.s0) & 31u));
    u1 = (u1 >> r.s1) | (u1 << ((32u - r.s1) & 31u));
    vec4 n0 = vec4(u0 & 0xFFFFu) * r.a0 + r.b0;
    vec4 f0 = vec4(u0 >> 16u) * r.a0 + r.b0;
    vec3 n1 = vec3(u1 & 0xFFFFu) * r.a1 + r.b1;
    vec3 f1 = vec3(u1 >> 16u) * r.a1 + r.b1;
#if defined(FILTER) && FILTER
    // every slab grows by the footprint at the node's farthest point from the camera, bounded by its box
    // (directions 0-2 are the axes)
    // (the rotation only swaps the halves: the box is the same either way)
    vec3 p = vec3(u0.xyz & 0xFFFFu) * uDopStepA.xyz + uDopBaseA.xyz + uSceneFromCamera;
    vec3 q = vec3(u0.xyz >> 16u) * uDopStepA.xyz + uDopBaseA.xyz + uSceneFromCamera;
    float g = gBoundGrow * length(max(abs(p), abs(q)));
    n0 -= g * abs(r.i0);
    f0 += g * abs(r.i0);
    n1 -= g * abs(r.i1);
    f1 += g * abs(r.i1);
#endif
    float tn = max(max(max(n0.x, n0.y), max(n0.z, n0.w)), max(max(n1.x, n1.y), n1.z));
    float tf = min(min(min(f0.x, f0.y), min(f0.z, f0.w)), min(min(f1.x, f1.y), f1.z));
#if defined(FILTER) && FILTER
    return empty ? vec2(INF, -INF) : vec2(tn, tf);
#else
    // an empty node (q_lo = 65535 > q_hi = 0 along every direction) needs no test: along each direction its
    // near bound lies past its far one, so tn > tf (the filtered mode's growth could close that gap)
    return vec2(tn, tf);
#endif
}

// ... through a leaf's cylinder (words: base a.xyz, radius a.w | unit axis b.xyz, length b.w; radius < 0:
// an empty leaf). The ray seen across the axis, o' + t d', is inside radius r while
// |d'|^2 t^2 + 2 (o'.d') t + |o'|^2 - r^2 <= 0; its discriminant is |d'|^2 r^2 - |o' x d'|^2 (no
// cancellation of two squares) and the roots are the stable pair q / |d'|^2, c / q (intervals.glsl:
// radius_interval, with one root and three divisions instead of four and four: the walk tests two
// cylinders a step). The height along the axis stays within [0, length]. float32 rounding moves the
// roots by far less than the radius's padding (bvh.py: segment_cylinders).
vec2 cylinder_interval(vec4 a, vec4 b, vec3 rd, vec3 shift) {
    vec3 o = -(a.xyz + shift);
    vec3 ez = b.xyz;
    float oz = dot(o, ez);
    float dz = dot(rd, ez);
#if defined(FILTER) && FILTER
    float r = a.w + gBoundGrow * (length(o) + b.w + a.w);
#else
    float r = a.w;
#endif
    vec3 op = o - oz * ez;
    vec3 dp = rd - dz * ez;
    float qa = dot(dp, dp);
    float qb = dot(op, dp);
    float qc = dot(op, op) - r * r;
    vec3 x = cross(op, dp);
    float disc = qa * (r * r) - dot(x, x);
    float q = -(qb + (qb >= 0.0 ? 1.0 : -1.0) * sqrt(max(disc, 0.0)));
    float ta = q / qa;
    float tb = q != 0.0 ? qc / q : ta;
    vec2 tube = qa == 0.0 ? (qc <= 0.0 ? vec2(-INF, INF) : vec2(INF, -INF))       // along the axis
                          : (disc < 0.0 ? vec2(INF, -INF) : vec2(min(ta, tb), max(ta, tb)));
    float iz = 1.0 / dz;
    float z0 = -oz * iz;
    float z1 = (b.w - oz) * iz;
    vec2 height = dz == 0.0 ? (oz >= 0.0 && oz <= b.w ? vec2(-INF, INF) : vec2(INF, -INF))
                            : vec2(min(z0, z1), max(z0, z1));
    return a.w >= 0.0 ? vec2(max(tube.x, height.x), min(tube.y, height.y)) : vec2(INF, -INF);
}

// Node `node`'s box from its parent's record (directions 0-2 of its DOP are the axes; a leaf: the box of
// its cylinder), scene-relative; an empty node gives lo > hi.
void node_box(int node, out vec3 lo, out vec3 hi) {
    int rec = (node + 1) >> 1;                  // the parent's record, record 0 for the root
    bool right = node > 0 && (node & 1) == 0;
    uvec4 w0 = record_word(4 * rec);
    uvec4 w1 = record_word(4 * rec + 1);
    uvec4 w2 = record_word(4 * rec + 2);
    uvec4 w3 = record_word(4 * rec + 3);
    uvec3 axes = right ? uvec3(w1.w, w2.xy) : w0.xyz;
    lo = vec3(axes & 0xFFFFu) * uDopStepA.xyz + uDopBaseA.xyz;
    hi = vec3(axes >> 16u) * uDopStepA.xyz + uDopBaseA.xyz;
    bool empty = (axes.x & 0xFFFFu) > (axes.x >> 16u);
    // a leaf: the box around its cylinder (a disc of radius r about ez reaches r sqrt(1 - ez_k^2) along k)
    vec4 a = uintBitsToFloat(right ? w2 : w0);
    vec4 b = uintBitsToFloat(right ? w3 : w1);
    vec3 tip = a.xyz + b.xyz * b.w;
    vec3 reach = a.w * sqrt(max(vec3(0.0), 1.0 - b.xyz * b.xyz));
    bool leaf = node >= uBvhLeaves - 1;
    lo = leaf ? min(a.xyz, tip) - reach : lo;
    hi = leaf ? max(a.xyz, tip) + reach : hi;
    empty = leaf ? a.w < 0.0 : empty;
    lo = empty ? vec3(1.0) : lo;
    hi = empty ? vec3(-1.0) : hi;
}

int node_level(uint node) {
    return findMSB(node + 1u);
}

// findMSB of a trail (bits below bit 24: a tree has at most 2^24 leaves, bvh.py: MAX_LEAVES) from
// the exponent of its float, exact below 2^24: findMSB is ~25 instructions a lane on llvmpipe, this 5.
int trail_msb(uint trail) {
    return trail == 0u ? -1 : (floatBitsToInt(float(int(trail))) >> 23) - 127;
}

bool bound_entered(vec2 iv, float tNear, float tCut) {
    return iv.x <= iv.y && iv.y >= tNear && iv.x <= tCut;
}

// Leave the current node for the far child of the deepest level on its path that still has one (heap
// arithmetic: the ancestor of node i at level k is ((i + 1) >> (level(i) - k)) - 1), or WALK_DONE.
void pop(inout uint node, inout uint trail) {
    int resume = trail_msb(trail);                                  // -1: nothing left
    int up = node_level(node) - resume;
    uint ancestor = ((node + 1u) >> uint(max(up - 1, 0))) - 1u;     // the near child at level resume + 1
    uint far = (ancestor & 1u) != 0u ? ancestor + 1u : ancestor - 1u;
    node = resume >= 0 ? far : WALK_DONE;
    trail &= ~(1u << uint(max(resume, 0)));
}

// Walk on to the next leaf whose cylinder the ray enters no later than tCut (depth first, the nearer
// child first), or to the end. Standing on a leaf, the walk stays: that leaf is the next one (the caller
// moves past it with pop once it is traversed). Whatever the walk skips is entered after tCut, and tCut
// only falls as nearer fibers are found, so nothing skipped can hold the nearest fiber.
// ray: dop_ray(rd, shift) (taken once per invocation by the caller); shift: uSceneFromCamera and depth:
// uBvhDepth, passed in as values the compiler cannot trace back to the uniforms (walk.frag: opaque):
// read inside the loop, llvmpipe gathered them lane by lane at every step.
void walk_to_leaf(inout uint node, inout uint trail, vec3 rd, DopRay ray, vec3 shift, int depth, float tNear,
                  float tCut) {
    // a fresh walk starts at the root without testing the root's own bound: its children's tests cover it
    // (a ray that misses the tree takes one step more), and the test cost ~300 instructions in each of the
    // two walks of every invocation, the second of which never starts fresh (llvmpipe runs it anyway)
    node = node == 0u && trail == 0u && uSegmentCount == 0 ? WALK_DONE : node;
    // the node's level is carried, not found again from its index at every step (findMSB is ~20
    // instructions a lane here); node_level(WALK_DONE) is -1, which ends the loop as the node does
    int level = node_level(node);
    int steps = 0;
    for (; node != WALK_DONE && level < depth && steps < WALK_CAP; steps++) {
        int left = 2 * int(node) + 1;
        // the node's record, both children's bounds: four texels of one row (a row holds whole records)
        ivec2 at = word_texel(4 * (int(node) + 1));
        uvec4 w0 = imageLoad(uBvhRecords, at);
        uvec4 w1 = imageLoad(uBvhRecords, at + ivec2(1, 0));
        uvec4 w2 = imageLoad(uBvhRecords, at + ivec2(2, 0));
        uvec4 w3 = imageLoad(uBvhRecords, at + ivec2(3, 0));
        // both kinds of test run for every lane (llvmpipe); the words are read once
        bool leaves = level + 1 == depth;
        vec2 l = leaves ? cylinder_interval(uintBitsToFloat(w0), uintBitsToFloat(w1), rd, shift)
                        : dop_interval(w0, w1.xyz, ray);
        vec2 r = leaves ? cylinder_interval(uintBitsToFloat(w2), uintBitsToFloat(w3), rd, shift)
                        : dop_interval(uvec4(w1.w, w2.xyz), uvec3(w2.w, w3.xy), ray);
        bool inL = bound_entered(l, tNear, tCut);
        bool inR = bound_entered(r, tNear, tCut);
        trail |= (inL && inR) ? (1u << uint(level)) : 0u;
        bool down = inL || inR;
        uint near = uint((inL && (!inR || l.x <= r.x)) ? left : left + 1);
        // pop (below) with the level known: up to the far child of the deepest level still pending
        int resume = trail_msb(trail);
        uint ancestor = ((node + 1u) >> uint(max(level - resume - 1, 0))) - 1u;
        uint far = (ancestor & 1u) != 0u ? ancestor + 1u : ancestor - 1u;
        node = down ? near : (resume >= 0 ? far : WALK_DONE);
        trail = down ? trail : trail & ~(1u << uint(max(resume, 0)));
        level = down ? level + 1 : resume + 1;
    }
    gWalkSteps += steps;
    gWalkRanOut = gWalkRanOut || (node != WALK_DONE && level < depth);
}

#endif
