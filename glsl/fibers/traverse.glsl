// traverse.glsl: find the fiber a ray hits inside one container segment (thesis chapter III, Appendix A).
//   FiberHit traverse(Segment seg, UnitRay ur)     in the cost pass, then reports a loop budget run out
//   FiberHit traverse_fibers(Segment seg, UnitRay ur)   the mode switch
//   void limit_traversal(Segment seg, inout UnitRay ur, float tKnown)   a nearer hit need not be sought
// TRAVERSAL selects the mode (mode.glsl):
//   0 fast   the thesis's order, first hit wins (straight.glsl; shaped.glsl for curved fibers).
//   1 exact  the same order, tested on until no later arc can be nearer: returns the nearest fiber.
//   2 brute  tests every fiber of every ring in [uBruteRange.x, uBruteRange.y) of the container's flat
//            fiber numbering; the renderer splits a container's fibers into chunks (one draw each) so no
//            invocation passes llvmpipe's 65,535 loop iterations; the depth test keeps the nearest.
// SHAPED 1 builds the traversal for curved fibers (curl, twist, ellipsoid: shaped.glsl) instead.
// The parts, one concept a file: hit.glsl (the best hit and the tie order), mode.glsl (mode and this
// draw's share of the fibers), counters.glsl (the cost counters and the loop canary), fiber_entry.glsl
// (one ray against one fiber), ray_path.glsl (the ray's arcs across the rings), candidates.glsl (the
// fibers an arc can hit), straight.glsl (the per-ring fiber loop for straight fibers).

#include "common/epsilon.glsl"
#include "geometry/container.glsl"
#include "fibers/layout.glsl"
#include "fibers/hit.glsl"
#include "fibers/counters.glsl"
#include "fibers/mode.glsl"
#include "fibers/fiber_entry.glsl"
#include "fibers/straight.glsl"

#ifndef FIBERS_TRAVERSE_GLSL
#define FIBERS_TRAVERSE_GLSL

#ifndef SHAPED
#define SHAPED 0
#endif

#if SHAPED
#include "fibers/shaped.glsl"     // traverse_shaped: curved fibers, in the frame that turns with the twist
#endif

void test_fiber(Segment seg, FiberRay fr, int ring, int j, inout FiberHit best) {
    if (ring == gSkipRing && j == gSkipFiber) return;
    vec2 c;
    float vEnd;
    fiber_center(seg.guide, ring, j, c, vEnd);
    int kind;
    gTests++;
    float s = fiber_entry(seg, fr, c, vEnd, kind);
    if (improves(best, s, ring, j)) {
        best.s = s;
        best.ring = ring;
        best.fiber = j;
        best.kind = kind;
        best.c = c;
    }
}

// A hit at world t = tKnown is known already (another container's, an earlier draw's): the ray's fibers
// past it cannot be the pixel's, so the traversal need not look there (EPS_KNOWN past it, so a tie is
// still found and broken as it was). A container whose proxy or leaf the ray meets behind a nearer one's
// fiber then costs its entry only, and one that it crosses partly (a joint) its stretch before the hit.
void limit_traversal(Segment seg, inout UnitRay ur, float tKnown) {
    float s = tKnown < INF ? world_to_unit_s(seg, ur, tKnown) : INF;
    float t = min(tKnown, 1e30);
    float rounding = EPS_KNOWN_T * (abs(t) + abs(ur.tb)) * ur.Dlen / (ur.wO * ur.wO);
    ur.sKnown = s < INF ? s + EPS_KNOWN * (abs(s) + 1e-2) + rounding : INF;
}

FiberHit traverse_fibers(Segment seg, UnitRay ur) {
#if SHAPED
    // curved fibers keep the whole stretch: a chord piece's ends follow its arc's, and cutting the arc
    // would move the fibers it approximates (shaped.glsl stops its arcs and pieces at sKnown instead)
    if (!(uFiberRadius > 0.0) || !(ur.s0 <= min(ur.s1, ur.sKnown))) return no_hit();   // see traverse_straight
    return traverse_shaped(seg, ur);
#else
    ur.s1 = min(ur.s1, ur.sKnown);      // a straight fiber's hit is exact on any stretch of the ray
    if (gMode != 2) return traverse_straight(seg, ur);
    if (!(uFiberRadius > 0.0) || !(ur.s0 <= ur.s1)) return no_hit();
    FiberHit best = no_hit();
    FiberRay fr = fiber_ray(seg, ur);
    for (int i = 0; i < uRings; i++) {
        gIters++;
        ivec2 nf = uRingN[i];
        int jBegin = max(0, uBruteRange.x - nf.y);
        int jEnd = min(nf.x, uBruteRange.y - nf.y);
        FiberRay fri = fiber_ray_ring(fr, i);           // this ring's fiber radius
        for (int j = jBegin; j < jEnd; j++) {
            gIters++;
            test_fiber(seg, fri, i, j, best);
        }
    }
    return best;
#endif
}

FiberHit traverse(Segment seg, UnitRay ur) {
    FiberHit hit = traverse_fibers(seg, ur);
#if defined(COST_PASS) && COST_PASS
    loop_canary();
#endif
    return hit;
}

#endif
