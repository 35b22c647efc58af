// straight.glsl: the traversal for straight fibers (thesis chapter III, Appendix A), fast and exact.
//   FiberHit traverse_straight(Segment seg, UnitRay ur)
// fast: the thesis's order, first hit wins: front arcs outer to inner, then the back arcs inner to outer
// (thesis 3.11 keeps them on a stack; here each is recomputed from its two ring boundaries); within an
// arc, fibers in the order the ray meets them (Figure 16). exact: the same order, but the candidates of
// an arc are tested up to two reaches past the latest improvement and traversal stops only when the next
// arc starts beyond the nearest hit so far: returns the nearest fiber.
// llvmpipe runs both sides of every branch and every loop at least once per SIMD batch: the loop is
// written without early returns or `continue` (docs/performance.md).
// Its candidate loop is not shared with traverse_shaped's, on purpose. Both use the same candidate runs
// (candidates.glsl), placement (layout.glsl) and tie order (hit.glsl: beats), but the per-fiber test and
// the state each keeps for its hit differ. A shared helper for the scan's rules (skip, tie, fast/exact
// stop) makes this loop write the best hit every pass instead of an arc-local copy merged once, and
// measured 1.3-2.5 % slower on the default preset in fast mode (llvmpipe, 640x360, min of 25
// process_time, four runs in both orders; exact mode and the shaped presets stayed within noise), so
// the two loops stay apart: a change to the scan's rules goes into both (shaped.glsl: traverse_shaped).

#include "common/epsilon.glsl"
#include "geometry/container.glsl"
#include "fibers/layout.glsl"
#include "fibers/hit.glsl"
#include "fibers/counters.glsl"
#include "fibers/mode.glsl"
#include "fibers/fiber_entry.glsl"
#include "fibers/candidates.glsl"
#include "fibers/ray_path.glsl"

#ifndef FIBERS_STRAIGHT_GLSL
#define FIBERS_STRAIGHT_GLSL

// Pieces of the ray, in the order it meets them: the front arcs of the rings it crosses twice (outer to
// inner), the deepest ring's two halves (split at the closest approach, so no piece sweeps more than 90
// degrees seen from the axis), then the back arcs (inner to outer; thesis 3.11 keeps them on a stack,
// here each is recomputed from its two boundaries). One loop visits them all, so the shader holds one
// copy of the candidate loop: a SIMD batch pays per piece for its costliest lane, not per call site.
// With uRingOrder the loop goes by ring index, pieces 0..K-1 the fronts (or first halves) and K..2K-1
// the backs (or second halves) of rings 0..K-1 and K-1..0: every lane of a batch visits the same ring
// at the same iteration, and a batch pays each ring's candidates at most twice (renderer.py: draw_ranges).
FiberHit traverse_straight(Segment seg, UnitRay ur) {
    FiberHit best = no_hit();
    FiberRay fr = fiber_ray(seg, ur);
    RayPath rp = ray_path(ur);
    int K = uRings;
    int deepest = deepest_ring(rp);
    bool byRing = uRingOrder != 0;
    // nothing to visit for a ray that misses the container, or for fibers of radius 0 (no fiber at all:
    // a ray through a centre would otherwise touch it), as in the reference
    bool any = ur.s0 <= ur.s1 && uFiberRadius > 0.0;
    int pieces = !any ? 0 : (byRing ? 2 * K : 2 * deepest + 2);
    // Consecutive pieces share a boundary: carry the last one crossed, so each piece places one more.
    vec2 carried = boundary_crossing(rp, 0);
    for (int p = 0; p < pieces; p++) {
        gIters++;
        // which ring, and which side of the closest approach
        bool back = byRing ? p >= K : p > deepest;
        int i = byRing ? (back ? 2 * K - 1 - p : p) : (back ? 2 * deepest + 1 - p : p);
        // (no `continue`: each would add a lane mask to every later assignment; a piece with nothing to
        // do gets no candidates instead)
        bool reached = i <= deepest;                    // by ring: lanes that do not reach ring i skip it
        bool axial = i == deepest;                      // the deepest ring: its inner edge is the axis
        vec2 fresh = boundary_crossing(rp, back ? i : i + 1);
        vec2 outer = back && !axial ? fresh : carried;
        vec2 inner = axial ? vec2(0.0) : (back ? carried : fresh);
        carried = reached && !axial ? fresh : carried;
        float xA = back ? inner.x : -outer.x;
        float xB = back ? outer.x : -inner.x;
        float psiA = max(back ? inner.y : -outer.y, rp.psi0);
        float psiB = min(back ? outer.y : -inner.y, rp.psi1);
        float sA = max(path_s(rp, xA), ur.s0);
        float sB = min(path_s(rp, xB), ur.s1);
        bool inside = reached && sA <= sB;             // else the stretch lies outside the container
        if (inside && sA >= best.s) break;              // pieces come in ray order: none later is nearer
        ivec2 share = ring_share(i, uFiberRange);
        bool open = inside && share.x < share.y;        // else none of this ring's fibers is in this draw
        gPieces += open ? 1 : 0;
        // the candidates: fibers whose slot, widened by the ring's reach, meets the piece's angles
        vec4 ring = uRingA[i];
        vec4 ringB = uRingB[i];
        float reach = ring.w + EPS_ANGLE;
        int n = uRingN[i].x;
        int dir = int(rp.sigma);
        float first = (rp.thD + rp.sigma * (psiA - reach) - ring.z) * ringB.z;
        float last = (rp.thD + rp.sigma * (psiB + reach) - ring.z) * ringB.z;
        int j0 = dir > 0 ? int(ceil(first)) : int(floor(first));
        int j1 = dir > 0 ? int(floor(last)) : int(ceil(last));
        int count = min(max(0, (j1 - j0) * dir + 1), n);
        ivec2 run0 = candidate_run(0, j0, dir, count, n, share);
        ivec2 run1 = candidate_run(1, j0, dir, count, n, share);
        // A hit nearer than one on candidate t lies before it along the ray, so its fiber's slot is at
        // most two reaches further on: exact mode stops that many candidates past its latest improvement.
        int after = int(ringB.w);
        int end = open ? run0.y + run1.y : 0;
        uint ringKey = ring_key(uSeed, seg.guide, i);
        FiberRay fri = fiber_ray_ring(fr, i);           // this ring's fiber radius
        int bestJ = -1;
        float bestS = best.s;
        vec2 bestC = vec2(0.0);
        int bestKind = 0;
        for (int t = 0; t < end; t++) {
            gIters++;
            gTests++;
            int j = candidate(run0, run1, dir, t);
            vec2 c;
            float vEnd;
            fiber_center_keyed(ring, ringB, ringKey, i, j, c, vEnd);
            int kind;
            float s = fiber_entry(seg, fri, c, vEnd, kind);
            if (i == gSkipRing && j == gSkipFiber) s = INF;
            // the best so far: this arc's, or the earlier arcs' (ties as brute force breaks them)
            bool mine = bestJ >= 0;
            bool better = beats(s, i, j, bestS, mine ? i : best.ring, mine ? bestJ : best.fiber);
            bestS = better ? s : bestS;
            bestJ = better ? j : bestJ;
            bestC = better ? c : bestC;
            bestKind = better ? kind : bestKind;
            // fast: the first fiber found wins
            end = !better ? end : (gMode == 0 ? t : min(end, t + 1 + after));
        }
        bool found = bestJ >= 0;
        best.s = found ? bestS : best.s;
        best.ring = found ? i : best.ring;
        best.fiber = found ? bestJ : best.fiber;
        best.c = found ? bestC : best.c;
        best.kind = found ? bestKind : best.kind;
        if (gMode == 0 && found) break;
    }
    return best;
}

#endif
