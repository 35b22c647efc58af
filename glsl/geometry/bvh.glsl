// bvh.glsl: the containers a ray enters, nearest first, from the hierarchy of app/render/bvh.py.
//   vec4      node_word(int k)                                           word k of the hierarchy (two a node)
//   uint      leaf_segment(int leaf)                                     scene index of a leaf's segment
//   Segment   fetch_segment(uint index)                                  scene segment, camera-relative
//   void      walk_to_leaf(inout uint node, inout uint trail, vec3 rd, float tNear, float tCut)
//   void      pop(inout uint node, inout uint trail)
//   bool      key_before(float ta, uint ia, float tb, uint ib)
// The tree is implicit and complete: node i has children 2i + 1 and 2i + 2, and leaf j (node
// uBvhLeaves - 1 + j) holds sorted segment j, so every step of the walk is the same two bound tests and
// the loop body stays short (llvmpipe runs every branch of a loop body for the whole SIMD batch, and
// every buffer read is a gather over its lanes). Inner nodes hold boxes, leaves their container's
// bounding cylinder. The walk keeps no stack: bit l of `trail` says the far child of the level-l node on
// the current path is still to visit, and the node to resume at follows from the current node's index
// (heap arithmetic), so a pixel's whole place in the walk is two integers: it can stop after any leaf
// and go on in the next draw (walk.frag). A bound the ray enters after the nearest fiber found so far
// holds no nearer one.
// The scene's words (hierarchy nodes, leaf order, segments) are read from images, WORD_ROW texels a row
// (renderer.py: WORD_ROW), not from storage buffers: llvmpipe reads a storage buffer at a per-lane index one
// lane and one component at a time (a loop that stalls on every component, ~300 ns a vec4 per 8-lane batch),
// an image with one gather per batch (~60 ns); harolongo's frame took 2.7x less CPU (docs/performance.md).
// Twin: app/render/bvh.py (segment_cylinders, segment_boxes, the layout); tests/render/test_bvh.py walks
// the same tree in numpy.

#ifndef GEOMETRY_BVH_GLSL
#define GEOMETRY_BVH_GLSL

#include "common/epsilon.glsl"
#include "geometry/container.glsl"

#ifndef WALK_CAP
#define WALK_CAP 4096       // walk steps per call; one that runs out is reported (walk.frag, cost output)
#endif

#define WORD_ROW_SHIFT 12        // renderer.py: WORD_ROW = 1 << WORD_ROW_SHIFT texels a row
layout(binding = 7, rgba32f) uniform readonly image2D uBvhNodes;        // two words per node
layout(binding = 8, r32ui) uniform readonly uimage2D uBvhOrder;         // scene index per leaf
layout(binding = 9, rgba32f) uniform readonly image2D uSegmentWords;    // five words per scene segment

uniform int uBvhLeaves;         // leaves: a power of two
uniform int uBvhDepth;          // log2(uBvhLeaves)
uniform int uSegmentCount;
uniform vec3 uSceneFromCamera;  // scene origin minus camera position: the tree and segments are scene-relative

const uint WALK_DONE = 0xFFFFFFFFu;
// The filtered mode's footprint half-width per unit distance (walk.frag sets it): every bound grows by the
// footprint at its farthest point, so a container a pixel's footprint reaches is walked into.
float gBoundGrow = 0.0;
int gWalkSteps = 0;             // walk steps (two bound tests each), all walks of this invocation
bool gWalkRanOut = false;

ivec2 word_texel(int k) {
    return ivec2(k & ((1 << WORD_ROW_SHIFT) - 1), k >> WORD_ROW_SHIFT);
}

vec4 node_word(int k) {
    return imageLoad(uBvhNodes, word_texel(k));
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

// Entry and exit t of the ray 0 + t rd (camera at the origin) through a box (an inner node's words: lo.xyz,
// hi.xyz, scene-relative); an empty node gives entry > exit. shift: the scene's origin seen from the
// camera (uSceneFromCamera) and shiftInvD = shift * invD, both passed in: read from the uniform inside
// the walk's loop, llvmpipe gathered it lane by lane at every step.
vec2 box_interval(vec4 lo, vec4 hi, vec3 invD, vec3 shift, vec3 shiftInvD) {
#if defined(FILTER) && FILTER
    vec3 p = lo.xyz + shift;
    vec3 q = hi.xyz + shift;
    bool full = p.x <= q.x;
    vec3 g = vec3(gBoundGrow * length(max(abs(p), abs(q))));
    p = full ? p - g : p;
    q = full ? q + g : q;
    vec3 ta = p * invD;
    vec3 tb = q * invD;
#else
    vec3 ta = lo.xyz * invD + shiftInvD;
    vec3 tb = hi.xyz * invD + shiftInvD;
#endif
    vec3 tn = min(ta, tb);
    vec3 tf = max(ta, tb);
    return lo.x <= hi.x ? vec2(max(max(tn.x, tn.y), tn.z), min(min(tf.x, tf.y), tf.z)) : vec2(INF, -INF);
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

// Node i's bound: its box, or for a leaf its cylinder.
vec2 node_interval(int i, vec3 rd, vec3 invD, bool leaf) {
    vec4 a = node_word(2 * i);
    vec4 b = node_word(2 * i + 1);
    vec3 shift = uSceneFromCamera;
    return leaf ? cylinder_interval(a, b, rd, shift) : box_interval(a, b, invD, shift, shift * invD);
}

int node_level(uint node) {
    return findMSB(node + 1u);
}

bool bound_entered(vec2 iv, float tNear, float tCut) {
    return iv.x <= iv.y && iv.y >= tNear && iv.x <= tCut;
}

// Leave the current node for the far child of the deepest level on its path that still has one (heap
// arithmetic: the ancestor of node i at level k is ((i + 1) >> (level(i) - k)) - 1), or WALK_DONE.
void pop(inout uint node, inout uint trail) {
    int resume = findMSB(trail);                                    // -1: nothing left
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
void walk_to_leaf(inout uint node, inout uint trail, vec3 rd, float tNear, float tCut) {
    // a zero component gives a large finite reciprocal: boxes then compare as slabs, with no NaN
    vec3 invD = 1.0 / mix(max(abs(rd), vec3(EPS_DIVISOR)), min(-abs(rd), vec3(-EPS_DIVISOR)), lessThan(rd, vec3(0.0)));
    if (node == 0u && trail == 0u) {
        // the start: the root itself (a tree of one leaf is one cylinder)
        vec2 root = node_interval(0, rd, invD, uBvhDepth == 0);
        node = uSegmentCount > 0 && bound_entered(root, tNear, tCut) ? 0u : WALK_DONE;
    }
    // the node's level is carried, not found again from its index at every step (findMSB is ~20
    // instructions a lane here); node_level(WALK_DONE) is -1, which ends the loop as the node does
    int level = node_level(node);
    vec3 shift = uSceneFromCamera;
    vec3 shiftInvD = shift * invD;
    int steps = 0;
    for (; node != WALK_DONE && level < uBvhDepth && steps < WALK_CAP; steps++) {
        int left = 2 * int(node) + 1;
        vec4 la = node_word(2 * left);
        vec4 lb = node_word(2 * left + 1);
        vec4 ra = node_word(2 * left + 2);
        vec4 rb = node_word(2 * left + 3);
        // both kinds of test run for every lane (llvmpipe); the words are read once
        bool leaves = level + 1 == uBvhDepth;
        vec2 l = leaves ? cylinder_interval(la, lb, rd, shift) : box_interval(la, lb, invD, shift, shiftInvD);
        vec2 r = leaves ? cylinder_interval(ra, rb, rd, shift) : box_interval(ra, rb, invD, shift, shiftInvD);
        bool inL = bound_entered(l, tNear, tCut);
        bool inR = bound_entered(r, tNear, tCut);
        trail |= (inL && inR) ? (1u << uint(level)) : 0u;
        bool down = inL || inR;
        uint near = uint((inL && (!inR || l.x <= r.x)) ? left : left + 1);
        // pop (below) with the level known: up to the far child of the deepest level still pending
        int resume = findMSB(trail);
        uint ancestor = ((node + 1u) >> uint(max(level - resume - 1, 0))) - 1u;
        uint far = (ancestor & 1u) != 0u ? ancestor + 1u : ancestor - 1u;
        node = down ? near : (resume >= 0 ? far : WALK_DONE);
        trail = down ? trail : trail & ~(1u << uint(max(resume, 0)));
        level = down ? level + 1 : resume + 1;
    }
    gWalkSteps += steps;
    gWalkRanOut = gWalkRanOut || (node != WALK_DONE && level < uBvhDepth);
}

#endif
