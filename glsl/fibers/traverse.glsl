// traverse.glsl: find the fiber a ray hits inside one container segment (thesis chapter III, Appendix A).
//   FiberHit traverse(Segment seg, UnitRay ur)     in the cost pass, then reports a loop budget run out
// TRAVERSAL selects the mode:
//   0 fast   the thesis's order, first hit wins: front arcs outer to inner, then the back arcs inner to
//            outer (thesis 3.11 keeps them on a stack; traverse_straight recomputes each from its two
//            ring boundaries); within an arc, fibers in the order the ray meets them (Figure 16).
//   1 exact  the same order, but the candidates of an arc are tested up to two reaches past the latest
//            improvement and traversal stops only when the next arc starts beyond the nearest hit so
//            far: returns the nearest fiber.
//   2 brute  tests every fiber of every ring in [uBruteRange.x, uBruteRange.y) of the container's flat
//            fiber numbering; the renderer splits a container's fibers into chunks (one draw each) so no
//            invocation passes llvmpipe's 65,535 loop iterations; the depth test keeps the nearest.
// An "arc" is the stretch of the ray's path (in the unit-space xy plane) inside one ring's annulus. The
// path crosses a ring twice (front and back arc) or, for the deepest ring it reaches, once; that stretch is
// split at the point closest to the axis so each piece sweeps less than 90 degrees. Only fibers whose slot
// angle lies within the piece's angles widened by the ring's reach can be hit; no other fiber is tested.
// Counters: gTests (fiber tests), gPieces (arcs visited), gIters (loop iterations, all loops).
// llvmpipe runs both sides of every branch and every loop at least once per SIMD batch: the straight-fiber
// path is written without early returns or `continue` (docs/performance.md).

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

// What every fiber test of one ray shares: the ray in unit space and the reciprocals that turn the
// per-fiber divisions into products. (llvmpipe runs a shader as SIMD lanes that execute every branch,
// so the cost of a traversal is the instructions of its loop bodies: keep them few and branch-free.)
struct FiberRay {
    vec2 o2;
    vec2 d2;
    float invA;     // 1 / |D.xy|^2 (0 for a ray along the axis)
    float ra;       // |D.xy| * fiber radius
    float oz;
    float invDz;    // 1 / D.z (0 when the ray is level)
    float dz;
    float s0, s1;
    float rf2;      // fiber radius squared
    float zScale;   // guide parameter -> local height, (h / (v1 - v0))
};

FiberRay fiber_ray(Segment seg, UnitRay ur) {
    FiberRay fr;
    fr.o2 = ur.O.xy;
    fr.d2 = ur.D.xy;
    float a = dot(fr.d2, fr.d2);
    fr.invA = a > 0.0 ? 1.0 / a : 0.0;
    fr.ra = sqrt(a) * uFiberRadius;
    fr.oz = ur.O.z;
    fr.dz = ur.D.z;
    fr.invDz = ur.D.z != 0.0 ? 1.0 / ur.D.z : 0.0;
    fr.s0 = ur.s0;
    fr.s1 = ur.s1;
    fr.rf2 = uFiberRadius * uFiberRadius;
    fr.zScale = seg.h / (seg.v1 - seg.v0);
    return fr;
}

// One fiber: a capped vertical cylinder of radius uFiberRadius about c, from the container's root plane
// to the fiber's length cut at guide parameter vEnd, inside the container interval [s0, s1]. Returns the
// entry parameter or INF; kind: 0 through the fiber's side, 1 its tip, 2 a container boundary.
// Roots as in circle_interval (intervals.glsl), with the discriminant factored so it never cancels.
float fiber_entry(Segment seg, FiberRay fr, vec2 c, float vEnd, out int kind) {
    // the length cut in unit space: none past the segment's tip end, no fiber before its root end
    float z = (vEnd - seg.v0) * fr.zScale;
    float zc = vEnd >= seg.v1 ? INF : z / (seg.r0 + seg.kappa * z);
    vec2 oc = fr.o2 - c;
    float b = dot(oc, fr.d2);
    float cc = dot(oc, oc) - fr.rf2;
    float crs = abs(oc.x * fr.d2.y - oc.y * fr.d2.x);
    float disc = (fr.ra - crs) * (fr.ra + crs);
    float q = -(b + (b >= 0.0 ? 1.0 : -1.0) * sqrt(max(disc, 0.0)));
    float ta = q * fr.invA;
    float tb = q != 0.0 ? cc / q : ta;
    vec2 cyl = fr.invA > 0.0 ? vec2(min(ta, tb), max(ta, tb))
                             : (cc <= 0.0 ? vec2(-INF, INF) : vec2(INF, -INF));   // along the axis
    float zs = (zc - fr.oz) * fr.invDz;
    vec2 zr = fr.dz > 0.0 ? vec2(-INF, zs) : (fr.dz < 0.0 ? vec2(zs, INF)
            : (fr.oz <= zc ? vec2(-INF, INF) : vec2(INF, -INF)));
    float sIn = max(max(cyl.x, zr.x), fr.s0);
    float sOut = min(min(cyl.y, zr.y), fr.s1);
    kind = sIn == cyl.x ? 0 : (sIn == zr.x ? 1 : 2);
    bool hit = disc >= 0.0 && sIn <= sOut && vEnd > seg.v0;
    return hit ? sIn : INF;
}

// Whether a hit at s on fiber (ring, j) replaces the best so far. Ties (a ray entering through a cap
// inside two overlapping fibers) go to the lower (ring, fiber), the order brute force tests them in, so
// every mode names the same fiber.
bool beats(float s, int ring, int j, float bestS, int bestRing, int bestFiber) {
    bool tie = s == bestS && (ring < bestRing || (ring == bestRing && j < bestFiber));
    return s < bestS || (tie && s < INF);
}

bool improves(FiberHit best, float s, int ring, int j) {
    return beats(s, ring, j, best.s, best.ring, best.fiber);
}

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

float wrap_pi(float a) {
    return a - 6.28318530718 * floor((a + 3.14159265359) / 6.28318530718);
}

// The share [lo, hi) of ring i's fibers this draw tests: the renderer splits the fibers over draws when
// one traversal could otherwise pass llvmpipe's loop budget (renderer.py: draw_ranges); unset, all.
ivec2 ring_share(int i, ivec2 range) {
    ivec2 nf = uRingN[i];
    return range.y <= range.x ? ivec2(0, nf.x) : clamp(range - nf.y, 0, nf.x);
}

// The candidates j0, j0 + dir, ... (count <= n of them, taken mod n) are at most two runs j = base + dir k,
// before and after the wrap past fiber 0; run r clipped to the share: (first j, number of fibers).
ivec2 candidate_run(int r, int j0, int dir, int count, int n, ivec2 share) {
    int m0 = j0 - n * int(floor(float(j0) / float(n)));   // the first candidate, in [0, n)
    int wrapK = dir > 0 ? n - m0 : m0 + 1;                 // k of the first candidate past the wrap
    int base = r == 0 ? m0 : m0 - dir * n;
    int kA = r == 0 ? 0 : wrapK;
    int kB = r == 0 ? min(count, wrapK) : count;
    kA = max(kA, dir > 0 ? share.x - base : base - share.y + 1);
    kB = min(kB, dir > 0 ? share.y - base : base - share.x + 1);
    return ivec2(base + dir * kA, max(0, kB - kA));
}

// The t-th candidate of the two runs: one loop over both, so that lanes of one SIMD batch whose runs
// split differently still cost the batch only the longest lane (llvmpipe's loop budget is per batch).
int candidate(ivec2 run0, ivec2 run1, int dir, int t) {
    return t < run0.y ? run0.x + dir * t : run1.x + dir * (t - run0.y);
}

// The ray's path seen along the axis (the unit-space xy plane) is a line that passes the axis at
// distance dist; x measures length along it from that closest point. A point at x is seen from the axis
// at the angle thD + sigma psi, psi = atan(x, dist) rising with x, so ring boundary k (radius r_k) is
// crossed at x = -+h_k, h_k = sqrt(r_k^2 - dist^2), and at psi = -+atan(h_k, dist): one root and one
// atan per boundary place both arcs of a ring, front and back.
struct RayPath {
    float x0;       // x at s = 0
    float sa;       // dx/ds: |D.xy| (0: the ray runs along the axis)
    float dist;     // closest approach to the axis
    float thD;      // angle of the closest point ...
    float sigma;    // ... and +1 when the angle grows along the ray, -1 when it falls
    float psi0;     // psi where the ray enters the container (s0) ...
    float psi1;     // ... and leaves it (s1)
};

RayPath ray_path(UnitRay ur) {
    RayPath rp;
    vec2 o2 = ur.O.xy;
    vec2 d2 = ur.D.xy;
    rp.sa = length(d2);
    // along the axis the path is a point: any line through it will do; take the one it is closest on
    vec2 dn = rp.sa > 0.0 ? d2 / rp.sa
            : (dot(o2, o2) > 0.0 ? normalize(vec2(-o2.y, o2.x)) : vec2(1.0, 0.0));
    rp.x0 = dot(o2, dn);
    float crs = o2.x * dn.y - o2.y * dn.x;
    rp.dist = abs(crs);
    rp.sigma = crs >= 0.0 ? 1.0 : -1.0;
    rp.thD = atan(dn.y, dn.x) - rp.sigma * 1.57079632679;
    rp.psi0 = atan(rp.x0 + ur.s0 * rp.sa, rp.dist);
    rp.psi1 = atan(rp.x0 + ur.s1 * rp.sa, rp.dist);
    return rp;
}

// The ray parameter at path position x (a ray along the axis is at x0 for every s).
float path_s(RayPath rp, float x) {
    float along = x == rp.x0 ? 0.0 : (x > rp.x0 ? INF : -INF);
    return rp.sa > 0.0 ? (x - rp.x0) / rp.sa : along;
}

float boundary_radius(int k) {
    return 1.0 - float(k) / float(uRings);
}

// (h, psi) of ring boundary k: the container's wall (k = 0) bounds nothing that [s0, s1] does not.
vec2 boundary_crossing(RayPath rp, int k) {
    float r = boundary_radius(k);
    float h = sqrt(max(0.0, (r - rp.dist) * (r + rp.dist)));
    return k == 0 ? vec2(INF, 1.57079632679) : vec2(h, atan(h, rp.dist));
}

// The ring whose annulus holds the path's closest approach: the deepest the ray reaches.
int deepest_ring(RayPath rp) {
    int K = uRings;
    int d = clamp(int((1.0 - rp.dist) * float(K)), 0, K - 1);
    // settle rounding against the boundaries as boundary_crossing computes them
    d += d < K - 1 && rp.dist < boundary_radius(d + 1) ? 1 : 0;
    d -= d > 0 && !(rp.dist < boundary_radius(d)) ? 1 : 0;
    return d;
}


#if SHAPED
#include "fibers/shaped.glsl"     // traverse_shaped: curved fibers, in the frame that turns with the twist
#endif

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
            float s = fiber_entry(seg, fr, c, vEnd, kind);
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

FiberHit traverse_fibers(Segment seg, UnitRay ur) {
#if SHAPED
    if (!(uFiberRadius > 0.0) || !(ur.s0 <= ur.s1)) return no_hit();    // see traverse_straight
    return traverse_shaped(seg, ur);
#else
    if (gMode != 2) return traverse_straight(seg, ur);
    if (!(uFiberRadius > 0.0) || !(ur.s0 <= ur.s1)) return no_hit();
    FiberHit best = no_hit();
    FiberRay fr = fiber_ray(seg, ur);
    for (int i = 0; i < uRings; i++) {
        gIters++;
        ivec2 nf = uRingN[i];
        int jBegin = max(0, uBruteRange.x - nf.y);
        int jEnd = min(nf.x, uBruteRange.y - nf.y);
        for (int j = jBegin; j < jEnd; j++) {
            gIters++;
            test_fiber(seg, fr, i, j, best);
        }
    }
    return best;
#endif
}

// llvmpipe ends every loop of an invocation silently once the invocation has run 65,535 loop iterations
// in all (each pass through a loop header counts, a loop's final test included). The renderer splits the
// fibers over draws so that should never happen (renderer.py: draw_ranges); should it happen anyway, a
// loop of two passes, a length the compiler cannot know, run after the traversal, stops after one, and
// gIters is raised to LOOP_CAP so that the iters and cost outputs say so instead of a fiber going missing
// in silence. Only the cost pass, whose outputs report it, pays for the canary: a loop costs a SIMD batch
// at least one pass of its body even where no lane needs it.
const int LOOP_CAP = 65535;

void loop_canary() {
    int trips = 0;
    for (int k = 0; k < 2 + min(uRings, 0); k++) trips++;
    if (trips < 2) gIters = max(gIters, LOOP_CAP);
}

FiberHit traverse(Segment seg, UnitRay ur) {
    FiberHit hit = traverse_fibers(seg, ur);
#if defined(COST_PASS) && COST_PASS
    loop_canary();
#endif
    return hit;
}
