// traverse.glsl: find the fiber a ray hits inside one container segment (thesis chapter III, Appendix A).
//   FiberHit traverse(Segment seg, UnitRay ur)     then reports a loop budget run out (loop_canary)
// TRAVERSAL selects the mode:
//   0 fast   the thesis's order, first hit wins: front arcs outer to inner, then the back arcs inner to
//            outer from a fixed-size stack (3.11); within an arc, fibers in the order the ray meets them
//            (Figure 16).
//   1 exact  the same order, but every candidate of an arc is tested and traversal stops only when the
//            next arc starts beyond the nearest hit so far: returns the nearest fiber.
//   2 brute  tests every fiber of every ring in [uBruteRange.x, uBruteRange.y) of the container's flat
//            fiber numbering; the renderer splits a container's fibers into chunks (one draw each) so no
//            invocation passes llvmpipe's 65,535 loop iterations; the depth test keeps the nearest.
// An "arc" is the stretch of the ray's path (in the unit-space xy plane) inside one ring's annulus. The
// path crosses a ring twice (front and back arc) or, for the deepest ring it reaches, once; that stretch is
// split at the point closest to the axis so each piece sweeps less than 90 degrees. Only fibers whose slot
// angle lies within the piece's angles widened by the ring's reach can be hit; no other fiber is tested.
// Counters: gTests (fiber tests), gPieces (arcs visited), gIters (loop iterations, all loops).

#include "fibers/layout.glsl"
#include "geometry/container.glsl"

#ifndef SHAPED
#define SHAPED 0
#endif

#ifndef TRAVERSAL
#define TRAVERSAL 1
#endif

struct FiberHit {
    float s;        // unit-space parameter, INF on a miss
    int ring;
    int fiber;
    int kind;       // 0 fiber side, 1 fiber tip (length cut), 2 container boundary (cap or joint)
    vec2 c;         // fiber centre in unit space
    vec2 dcdv;      // how the centre moves with the guide parameter (curved fibers; 0 when straight)
};

int gTests = 0;
int gPieces = 0;
int gIters = 0;
int gMode = TRAVERSAL;          // a shadow ray switches to 0 (any hit) for itself
int gSkipRing = -1;             // a shadow ray starts on this fiber: never count it as a blocker
int gSkipFiber = -1;
uniform ivec2 uBruteRange;
uniform ivec2 uFiberRange;      // fast, exact: test only fibers [x, y) of the container's flat numbering
uniform int uRingOrder;         // 1: the loops after the ring loop go by ring index (renderer.py: draw_ranges)

#if SHAPED
#include "fibers/curved.glsl"
#endif

FiberHit no_hit() {
    FiberHit h;
    h.s = INF;
    h.ring = -1;
    h.fiber = -1;
    h.kind = 0;
    h.c = vec2(0.0);
    h.dcdv = vec2(0.0);
    return h;
}

// One fiber: a capped vertical cylinder of radius uFiberRadius about c, from the container's root plane
// to the fiber's length cut, inside the container interval. Returns the entry parameter or INF.
float fiber_test(Segment seg, UnitRay ur, vec2 c, float vEnd, out int kind) {
    gTests++;
    kind = 0;
    float zc = z_cut_unit(seg, vEnd);
    if (zc == -INF) return INF;
    vec2 cyl = circle_interval(ur.O.xy, ur.D.xy, c, uFiberRadius);
    vec2 z = slab(ur.O.z, ur.D.z, -INF, zc);
    float sIn = max(max(cyl.x, z.x), ur.s0);
    float sOut = min(min(cyl.y, z.y), ur.s1);
    if (!(sIn <= sOut)) return INF;
    kind = sIn == cyl.x ? 0 : (sIn == z.x ? 1 : 2);
    return sIn;
}

// Whether a hit at s on fiber (ring, j) replaces the best so far. Ties (a ray entering through a cap
// inside two overlapping fibers) go to the lower (ring, fiber), the order brute force tests them in, so
// every mode names the same fiber.
bool improves(FiberHit best, float s, int ring, int j) {
    bool tie = s == best.s && (ring < best.ring || (ring == best.ring && j < best.fiber));
    return s < best.s || (tie && s < INF);
}

void test_fiber(Segment seg, UnitRay ur, int ring, int j, inout FiberHit best) {
    if (ring == gSkipRing && j == gSkipFiber) return;
    vec2 c;
    float vEnd;
    fiber_center(seg.guide, ring, j, c, vEnd);
    int kind;
    float s = fiber_test(seg, ur, c, vEnd, kind);
    if (improves(best, s, ring, j)) {
        best.s = s;
        best.ring = ring;
        best.fiber = j;
        best.kind = kind;
        best.c = c;
    }
}

float wrap_pi(float a) {
    return a - 6.28318530718 * floor((a + 3.14159265359) / 6.28318530718);
}

// The share [lo, hi) of ring i's fibers this draw tests: the renderer splits the fibers over draws when
// one traversal could otherwise pass llvmpipe's loop budget (renderer.py: draw_ranges); unset, all.
ivec2 ring_share(int i, ivec2 range) {
    int n = uRingN[i].x;
    if (range.y <= range.x) return ivec2(0, n);
    return clamp(range - uRingN[i].y, 0, n);
}

// The candidates j0, j0 + dir, ... (count <= n of them, taken mod n) are at most two runs j = base + dir k,
// before and after the wrap past fiber 0; run r clipped to the share: (first j, number of fibers).
ivec2 candidate_run(int r, int j0, int dir, int count, int n, ivec2 share) {
    int m0 = j0 - n * int(floor(float(j0) / float(n)));   // the first candidate, in [0, n)
    int wrapK = dir > 0 ? n - m0 : m0 + 1;                 // k of the first candidate past the wrap
    int base = r == 0 ? m0 : m0 - dir * n;
    int kA = r == 0 ? 0 : wrapK;
    int kB = r == 0 ? min(count, wrapK) : count;
    if (dir > 0) {
        kA = max(kA, share.x - base);
        kB = min(kB, share.y - base);
    } else {
        kA = max(kA, base - share.y + 1);
        kB = min(kB, base - share.x + 1);
    }
    return ivec2(base + dir * kA, max(0, kB - kA));
}

// The t-th candidate of the two runs: one loop over both, so that lanes of one SIMD batch whose runs
// split differently still cost the batch only the longest lane (llvmpipe's loop budget is per batch).
int candidate(ivec2 run0, ivec2 run1, int dir, int t) {
    return t < run0.y ? run0.x + dir * t : run1.x + dir * (t - run0.y);
}

// Test the candidates of ring i on the piece [sA, sB] of the ray. Returns true when traversal is over.
bool visit_piece(Segment seg, UnitRay ur, int i, float sA, float sB, inout FiberHit best) {
    sA = max(sA, ur.s0);
    sB = min(sB, ur.s1);
    if (!(sA <= sB)) return false;          // this stretch lies outside the container (caps, joints)
    if (sA >= best.s) return true;          // pieces come in ray order: nothing later can be nearer
    ivec2 share = ring_share(i, uFiberRange);
    if (share.x >= share.y) return false;   // none of this ring's fibers is in this draw
    gPieces++;
    vec2 pA = ur.O.xy + sA * ur.D.xy;
    vec2 pB = ur.O.xy + sB * ur.D.xy;
    // a piece can touch the axis only at one end (a ray through the axis); take the other end's angle
    float thA = dot(pA, pA) > 0.0 ? atan(pA.y, pA.x) : atan(pB.y, pB.x);
    float thB = dot(pB, pB) > 0.0 ? atan(pB.y, pB.x) : thA;
    float span = wrap_pi(thB - thA);
    vec4 ring = uRingA[i];
    float reach = ring.w + EPS_ANGLE;
    int n = uRingN[i].x;
    int dir = span >= 0.0 ? 1 : -1;
    float first = (thA - float(dir) * reach - ring.z) / ring.y;
    float last = (thA + span + float(dir) * reach - ring.z) / ring.y;
    int j0 = dir > 0 ? int(ceil(first)) : int(floor(first));
    int j1 = dir > 0 ? int(floor(last)) : int(ceil(last));
    int count = min(max(0, (j1 - j0) * dir + 1), n);
    ivec2 run0 = candidate_run(0, j0, dir, count, n, share);
    ivec2 run1 = candidate_run(1, j0, dir, count, n, share);
    for (int t = 0; t < run0.y + run1.y; t++) {
        gIters++;
        test_fiber(seg, ur, i, candidate(run0, run1, dir, t), best);
        if (gMode == 0 && best.s < INF) return true;   // fast: the first fiber found wins
    }
    return false;
}


#if SHAPED
// --- curved fibers -------------------------------------------------------------------------------------
// A ring's fibers no longer sit in its annulus at every height: the ellipsoid scales them by E(v) in
// [eLo, eHi] over this segment and the curl moves them by up to its amplitude. So each ring gets a band
// [inner, outer] that holds its fibers at every height of the segment, bands of neighbouring rings may
// overlap, and arcs are visited in order of where they start: fronts of the rings crossed twice (outer
// to inner), first halves of the rings crossed once, their second halves, then the backs (inner to outer).

struct Bands { float eLo; float eHi; };

Bands segment_bands(Segment seg) {
    float vLo = unit_to_v(seg, seg.zLo / (seg.r0 + seg.kappa * seg.zLo));
    float vHi = unit_to_v(seg, seg.zHi / (seg.r0 + seg.kappa * seg.zHi));
    float ea = shape_scale(vLo), eb = shape_scale(vHi);
    Bands b;
    b.eLo = min(ea, eb);
    b.eHi = (min(vLo, vHi) <= 0.5 && max(vLo, vHi) >= 0.5) ? 1.0 : max(ea, eb);
    return b;
}

vec2 ring_band(int i, Bands b) {
    float rho = uRingA[i].x, dr = uRingB[i].x;
    float grow = uFiberRadius + uCurlAmplitude + 1e-6;
    return vec2(max(0.0, b.eLo * (rho - dr) - grow), b.eHi * (rho + dr) + grow);
}

float shaped_reach(int i, Bands b) {
    float dMin = b.eLo * (uRingA[i].x - uRingB[i].x);
    float r = uFiberRadius + uCurlAmplitude;
    float disc = dMin > r ? asin(r / dMin) : 3.14159265359;
    return uRingB[i].y + disc + EPS_ANGLE;
}

// Test ring i's candidates on the arc [sA, sB]; in brute mode every fiber of the chunk. True: done.
bool visit_shaped(Segment seg, UnitRay ur, int i, float sA, float sB, Bands bands, inout FiberHit best) {
    float a = max(sA, ur.s0);
    float b = min(sB, ur.s1);
    if (!(a <= b)) return false;
    if (gMode != 2 && a >= best.s) return true;
    ivec2 share = ring_share(i, gMode == 2 ? uBruteRange : uFiberRange);
    if (share.x >= share.y) return false;   // none of this ring's fibers is in this draw
    gPieces++;
    int n = uRingN[i].x;
    int j0, count, dir;
    if (gMode == 2) {
        j0 = 0;
        count = n;
        dir = 1;
    } else {
    vec2 pA = ur.O.xy + a * ur.D.xy;
    vec2 pB = ur.O.xy + b * ur.D.xy;
    float thA = dot(pA, pA) > 0.0 ? atan(pA.y, pA.x) : atan(pB.y, pB.x);
    float thB = dot(pB, pB) > 0.0 ? atan(pB.y, pB.x) : thA;
    float span = wrap_pi(thB - thA);
    vec2 tw = twist_range(unit_to_v(seg, ur.O.z + a * ur.D.z), unit_to_v(seg, ur.O.z + b * ur.D.z), i);
    float reach = shaped_reach(i, bands);
    vec4 ring = uRingA[i];
    dir = span >= 0.0 ? 1 : -1;
    float first = dir > 0 ? thA - tw.y - reach : thA - tw.x + reach;
    float last = dir > 0 ? thA + span - tw.x + reach : thA + span - tw.y - reach;
    first = (first - ring.z) / ring.y;
    last = (last - ring.z) / ring.y;
    j0 = dir > 0 ? int(ceil(first)) : int(floor(first));
    int j1 = dir > 0 ? int(floor(last)) : int(ceil(last));
    count = min(max(0, (j1 - j0) * dir + 1), n);
    }
    ivec2 run0 = candidate_run(0, j0, dir, count, n, share);
    ivec2 run1 = candidate_run(1, j0, dir, count, n, share);
    for (int t = 0; t < run0.y + run1.y; t++) {
        gIters++;
        int j = candidate(run0, run1, dir, t);
        if (i == gSkipRing && j == gSkipFiber) continue;
        vec2 rest;
        float vEnd;
        fiber_center(seg.guide, i, j, rest, vEnd);
        int kind;
        float s = curved_fiber_test(seg, ur, rest, fiber_curl_phase(seg.guide, i, j), i, vEnd, bands.eLo,
                                    a, b, kind);
        if (improves(best, s, i, j)) {
            best.s = s;
            best.ring = i;
            best.fiber = j;
            best.kind = kind;
            float v = unit_to_v(seg, ur.O.z + s * ur.D.z);
            float phase = fiber_curl_phase(seg.guide, i, j);
            best.c = fiber_center_at(rest, v, i, phase);
            best.dcdv = (fiber_center_at(rest, v + 1e-3, i, phase) - fiber_center_at(rest, v - 1e-3, i, phase)) / 2e-3;
        }
        if (gMode == 0 && best.s < INF) return true;
    }
    return false;
}

FiberHit traverse_shaped(Segment seg, UnitRay ur) {
    FiberHit best = no_hit();
    Bands bands = segment_bands(seg);
    vec2 o2 = ur.O.xy;
    vec2 d2 = ur.D.xy;
    float a = dot(d2, d2);
    float sMid = a > 0.0 ? -dot(o2, d2) / a : ur.s0;
    vec2 backs[MAX_RINGS];      // back arcs of the rings crossed twice
    float halves[MAX_RINGS];    // where the second half of a ring crossed once ends
    int nTwice = 0;
    int nOnce = 0;
    for (int i = 0; i < uRings; i++) {
        gIters++;
        vec2 band = ring_band(i, bands);
        vec2 outer = circle_interval(o2, d2, vec2(0.0), band.y);
        if (outer.x > outer.y) break;                       // this band and every inner one are missed
        vec2 inner = circle_interval(o2, d2, vec2(0.0), band.x);
        if (inner.x <= inner.y && nOnce == 0) {
            if (visit_shaped(seg, ur, i, outer.x, inner.x, bands, best)) return best;
            backs[nTwice++] = vec2(inner.y, outer.y);
        } else {
            if (visit_shaped(seg, ur, i, outer.x, sMid, bands, best)) return best;
            halves[nOnce++] = outer.y;
        }
    }
    // With uRingOrder these loops go over all ring indices, not over this ray's list: every lane of a SIMD
    // batch then visits the same ring at the same iteration, and a batch pays each ring's candidates once
    // per visit whatever its lanes do. The renderer asks for it only where the loop budget is tight: the
    // extra iterations cost a few percent.
    for (int i = uRingOrder != 0 ? 0 : nTwice; i < (uRingOrder != 0 ? uRings : nTwice + nOnce); i++) {
        gIters++;
        if (i < nTwice || i >= nTwice + nOnce) continue;
        if (visit_shaped(seg, ur, i, sMid, halves[i - nTwice], bands, best)) return best;
    }
    for (int i = uRingOrder != 0 ? uRings - 1 : nTwice - 1; i >= 0; i--) {
        gIters++;
        if (i >= nTwice) continue;
        if (visit_shaped(seg, ur, i, backs[i].x, backs[i].y, bands, best)) return best;
    }
    return best;
}
#endif

FiberHit traverse_fibers(Segment seg, UnitRay ur) {
    // radius 0 is no fiber at all (a ray through a centre would otherwise touch it), as in the reference
    if (!(uFiberRadius > 0.0)) return no_hit();
#if SHAPED
    return traverse_shaped(seg, ur);
#endif
    FiberHit best = no_hit();
    int K = uRings;
    if (gMode == 2) {
    for (int i = 0; i < K; i++) {
        gIters++;
        ivec2 nf = uRingN[i];
        int jBegin = max(0, uBruteRange.x - nf.y);
        int jEnd = min(nf.x, uBruteRange.y - nf.y);
        for (int j = jBegin; j < jEnd; j++) {
            gIters++;
            test_fiber(seg, ur, i, j, best);
        }
    }
    return best;
    }
    vec2 o2 = ur.O.xy;
    vec2 d2 = ur.D.xy;
    float a = dot(d2, d2);
    vec2 backStack[MAX_RINGS];              // thesis 3.11: back arcs, pushed outer to inner
    vec2 outer = circle_interval(o2, d2, vec2(0.0), 1.0);
    int deepest = K - 1;
    for (int i = 0; i < K - 1; i++) {
        gIters++;
        vec2 inner = circle_interval(o2, d2, vec2(0.0), 1.0 - float(i + 1) / float(K));
        if (inner.x > inner.y) { deepest = i; break; }   // the path stays in this ring: deepest reached
        if (visit_piece(seg, ur, i, outer.x, inner.x, best)) return best;
        backStack[i] = vec2(inner.y, outer.y);
        outer = inner;
    }
    // deepest ring: one stretch, split where the path comes closest to the axis
    float sMid = a > 0.0 ? -dot(o2, d2) / a : ur.s0;
    if (visit_piece(seg, ur, deepest, outer.x, sMid, best)) return best;
    if (visit_piece(seg, ur, deepest, sMid, outer.y, best)) return best;
    for (int i = uRingOrder != 0 ? K - 2 : deepest - 1; i >= 0; i--) {   // uRingOrder: see traverse_shaped
        gIters++;
        if (i >= deepest) continue;
        if (visit_piece(seg, ur, i, backStack[i].x, backStack[i].y, best)) return best;
    }
    return best;
}

// llvmpipe ends every loop of an invocation silently once the invocation has run 65,535 loop iterations
// in all (each pass through a loop header counts, a loop's final test included). The renderer splits the
// fibers over draws so that should never happen (renderer.py: draw_ranges); should it happen anyway, a
// loop of a length the compiler cannot know, run after the traversal, is cut short, and gIters is raised
// to LOOP_CAP so that the iters and cost outputs say so instead of a fiber going missing in silence.
const int LOOP_CAP = 65535;

void loop_canary() {
    int trips = 0;
    for (int k = 0; k <= uRings; k++) trips++;
    if (trips <= uRings) gIters = max(gIters, LOOP_CAP);
}

FiberHit traverse(Segment seg, UnitRay ur) {
    FiberHit hit = traverse_fibers(seg, ur);
    loop_canary();
    return hit;
}
