// shaped.glsl: the traversal for curved fibers (curl, twist, ellipsoid); traverse.glsl dispatches here.
//   FiberHit traverse_shaped(Segment seg, UnitRay ur)
// A ring's fibers no longer sit in its annulus at every height: the ellipsoid scales them by E(v) in
// [eLo, eHi] over this segment and the curl, frizz and noise move them by up to shape_displacement(). So
// each ring gets a band
// [inner, outer] that holds its fibers at every height of the segment (bands of neighbouring rings may
// overlap), and the ray's arcs through the bands are visited in order of where they start: the fronts of
// the bands crossed twice (outer to inner), the first halves of the bands crossed once (split at the
// ray's closest approach to the axis), their second halves (inner to outer, all starting at the closest
// approach), then the backs (inner to outer). One loop visits them all, as traverse_straight's does.
// The bands are the untwisted ring's (the twist keeps every distance to the axis). The arc is cut into
// chord pieces (curved.glsl: chord_pieces, as many as the fibers' bend over the ray's climb needs); on a
// piece each fiber is the chord between its centres at the piece's ends and the ray is straight (the
// container's frame: piece_entry), and only the fibers whose slot, widened by the ring's reach (jitter,
// the displacement and the fiber's disc), meets the angles the ray sweeps seen in the frame that turns
// with the ring's twist are tested on it (the piece's window: piece_window). The twist widens a window
// only on a piece where its rate meets the ray's own sweep, by at most its turn over the piece.
// exact: a piece's candidates up to two reaches past its latest improvement are tested, and the pieces
// (and arcs) stop once the next one starts beyond the nearest hit so far. fast: the first hit wins. brute: every fiber of the draw's share on every
// piece of every arc.
// The loops are written in traverse_straight's style: no early return and no `continue`; a piece or arc
// with nothing to do gets no candidates (docs/performance.md).
// Twin: app/reference.py (shaped_nearest_segment).

#include "common/epsilon.glsl"
#include "common/hash.glsl"
#include "geometry/intervals.glsl"
#include "geometry/container.glsl"
#include "fibers/layout.glsl"
#include "fibers/hit.glsl"
#include "fibers/counters.glsl"
#include "fibers/mode.glsl"
#include "fibers/fiber_entry.glsl"
#include "fibers/candidates.glsl"
#include "fibers/shape.glsl"
#include "fibers/curved.glsl"

#ifndef FIBERS_SHAPED_GLSL
#define FIBERS_SHAPED_GLSL

#ifndef SHAPE_ELLIPSOID
#define SHAPE_ELLIPSOID 1   // 0: built for ellipsoid 0 (the bands of the segment are the arc's)
#endif

// Exact mode's stop at the best hit's point and the length screen (in traverse_shaped) pay where the
// displacement widens the windows (curl, frizz, noise: 10% and 40% fewer fiber tests on the bench's curled
// scene); for twist or the ellipsoid alone their per-candidate work cost more than it saved
// (docs/shaped-traversal.md).
#define SHAPED_POINT_STOP (SHAPE_CURL != 0 || SHAPE_FRIZZ)
#ifndef SHAPED_SCREEN
#define SHAPED_SCREEN (SHAPE_CURL != 0 || SHAPE_FRIZZ)   // a define of 0 turns it off (the tests compare)
#endif
#ifndef SHAPED_TURNED_WINDOW
#define SHAPED_TURNED_WINDOW 1      // 0: every piece's window the box (piece_window; the tests compare)
#endif

// The layout's uniforms the loops below read, copied once per invocation (shape.glsl says why): the
// seed and the fiber ranges are never negative, so abs leaves them as they are.
uint sSeed = uint(abs(int(uSeed)));
ivec2 sFiberRange = abs(uFiberRange);
ivec2 sBruteRange = abs(uBruteRange);
float sLengthJitter = abs(uLengthJitter);

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
    float grow = sFiberRadius + shape_displacement() + EPS_BAND;
    return vec2(max(0.0, b.eLo * (rho - dr) - grow), b.eHi * (rho + dr) + grow);
}

// Angular reach of ring i's fibers about their slots: the jitter, then the disc of radius r = fiber
// radius + displacement about Q, the point of the fiber's rest chord (between its scaled, turned rest
// positions at the piece's ends), seen from the axis. A point P within r of Q is within asin(r / |Q|) of
// Q's direction, and also within asin(r / |P|): Q lies on the half-line through the axis at its angle,
// and P is |P| sin(angle) from that line. |Q| >= eLo (rho - maxDr) cos(dTau / 2), dTau the twist over
// the piece (chordCos). So a piece whose ray keeps away from the axis (rayMin: its nearest distance)
// narrows the reach of the inner rings, where the disc alone would take the whole ring.
float shaped_disc(int i, Bands b, float rayMin, float chordCos) {
    float dMin = max(b.eLo * (uRingA[i].x - uRingB[i].x) * chordCos, rayMin);
    float r = sFiberRadius + shape_displacement();
    return dMin > r ? asin(r / dMin) : 3.14159265359;
}

float shaped_reach(int i, Bands b, float rayMin, float chordCos) {
    return uRingB[i].y + shaped_disc(i, b, rayMin, chordCos) + EPS_ANGLE;
}

// (cos, sin) of the disc plus EPS_ANGLE, the point stop's turn (traverse_shaped), without a sine or a
// cosine: the disc is asin(x), so its cosine is sqrt(1 - x^2), and EPS_ANGLE is added by a constant
// rotation. Rounding moves the angle by ~1e-7, inside the EPS_ANGLE it has to spare. A disc of pi (the
// chord reaches the fibers' axis side) comes out as x = 1: the stop is off there anyway (reach > 1.5).
vec2 shaped_turn(int i, Bands b, float rayMin, float chordCos) {
    float dMin = max(b.eLo * (uRingA[i].x - uRingB[i].x) * chordCos, rayMin);
    float r = sFiberRadius + shape_displacement();
    float x = dMin > r ? r / dMin : 1.0;                // shaped_disc's quotient: one division for both
    vec2 d = vec2(sqrt(max(0.0, (1.0 - x) * (1.0 + x))), x);
    const vec2 e = vec2(cos(EPS_ANGLE), sin(EPS_ANGLE));
    return vec2(d.x * e.x - d.y * e.y, d.y * e.x + d.x * e.y);
}

// The slots a chord piece's ray can meet, as angles in the ring's turning frame (slot j at rot + j dphi).
// A fiber's rest chord on the piece runs between its rest position turned by tau0 and by tau1 (the
// ring's twist at the piece's ends), so in the container's frame it lies in the wedge of its rest angle
// plus [min(tau0, tau1), max(tau0, tau1)]; a hit needs the ray's angle theta within the reach of that
// wedge. theta runs one way along the straight ray: the box window is theta's range less the twist's,
// scanned in theta's order. Tighter where it holds: in the frame turned by the twist interpolated along
// the piece, tau0 + (s - s0) dTau / L, the rest chord keeps its rest angle to within epsF (the chord of
// two points dTau apart strays from the turning angle by at most 0.0161 |dTau|^3 of its radius, and the
// scale's change E1 - E0 adds |E1 - E0| |dTau| / 4; over its distance from the axis, >= eMin
// cos(dTau / 2)), and the ray's angle there, psi = theta - tau, runs one way unless the twist's rate
// meets theta's, |O.xy x D.xy| / |p|^2 (one sign over |p|^2 in [rayMin^2, the ends']): then psi's range
// widened by the reach and epsF is the window, scanned in psi's order (epsF kept below EPS_TURNED_CHORD,
// so the window is at most 2 EPS_TURNED_CHORD wider than the box: renderer.py's loop bound).
struct PieceWindow {
    float start;        // where the scan starts (before the reach), and the signed span it runs over
    float span;
    int dir;            // the scan's order: +1 or -1
    float reach;        // added on both sides
    float after;        // exact: how far past an improvement a nearer hit's slot can lie
    bool thetaOrder;    // the scan runs in theta's order (the point stop needs it: shaped_candidate)
};

PieceWindow piece_window(float thA, float spanX, RingPoint P0, RingPoint P1, float cr, float rayMin,
                         float reach, float chordCos) {
    float dTau = P1.tau - P0.tau;
    float ad = abs(dTau);
    int dirX = spanX >= 0.0 ? 1 : -1;
    PieceWindow w;
    w.start = thA - (dirX > 0 ? max(P0.tau, P1.tau) : min(P0.tau, P1.tau));
    w.span = spanX + float(dirX) * ad;
    w.dir = dirX;
    w.reach = reach;
    w.after = 2.0 * reach + ad;
    w.thetaOrder = true;
#if SHAPE_TWIST && SHAPED_TURNED_WINDOW
    float L = P1.s - P0.s;
    float dmax2 = max(dot(P0.p, P0.p), dot(P1.p, P1.p));
    bool oneWay = ad <= 1.5 && (cr * L - dTau * dmax2) * (cr * L - dTau * rayMin * rayMin) > 0.0;
    float eMin = min(P0.e, P1.e), eMax = max(P0.e, P1.e);
    float x = (eMax * 0.02 * ad * ad * ad + (eMax - eMin) * 0.25 * ad) / max(eMin * chordCos, EPS_DIVISOR);
    float epsF = 1.5708 * x;                        // asin(x) <= x pi / 2; <= EPS_TURNED_CHORD
    float spanT = spanX - dTau;
    oneWay = oneWay && epsF <= EPS_TURNED_CHORD;
    int dirT = spanT >= 0.0 ? 1 : -1;
    w.start = oneWay ? thA - P0.tau : w.start;
    w.span = oneWay ? spanT : w.span;
    w.dir = oneWay ? dirT : w.dir;
    w.reach = oneWay ? reach + epsF : w.reach;
    w.after = oneWay ? 2.0 * (reach + epsF) : w.after;
    w.thetaOrder = !oneWay || dirT == dirX;
#endif
    return w;
}

// The distance from the axis to the chord from a to b.
float chord_distance(vec2 a, vec2 b) {
    vec2 d = b - a;
    float len2 = dot(d, d);
    float t = len2 > 0.0 ? clamp(-dot(a, d) / len2, 0.0, 1.0) : 0.0;
    return length(a + t * d);
}

float shaped_curl_phase(uint ringKey, int ring, int j) {
#if HASH_THESIS
    float slotDeg = degrees(uRingA[ring].z + float(j) * uRingA[ring].y);
    return thesis_random(slotDeg, float(ring), float(CH_CURL));
#else
    return key_random(lowbias32(ringKey ^ uint(j)), CH_CURL);   // fiber_key, from the ring's part
#endif
}

// A chord piece as its candidates see it, and what its scan carries from one candidate to the next.
struct ShapedPiece {
    RingPoint P0, P1;
    float invLen;       // 1 / (P1.s - P0.s), 0 for a piece of no length
    vec2 curlStep;      // ring_curl_step(P0, P1)
    vec4 A, B;          // the ring's uniforms
    uint ringKey;
    int ring;
    int after;          // exact: candidates past an improvement that can still be nearer
    int dir;            // +1 or -1: the order of the slots along the sweep
    vec2 turn;          // (cos, sin) that turns a rest direction back by the disc, against dir
    bool angled;        // the point stop may compare angles (they lie within half a turn, theta's order)
    vec2 dTau;          // (cos, sin) of the twist from P0 to P1
    bool backAtEnd;     // the point stop turns the rest position by the twist at P1 (else at P0)
};
struct ShapedScan {
    FiberHit best;
    bool found;         // this arc has improved the best
    int end;            // the candidates to scan: [0, end)
    vec2 H;             // the chord's point at the best hit (or the piece's end while it lies beyond)
};

// Candidate t (fiber j) of a piece: its test, the best hit, and exact mode's and fast mode's stops.
void shaped_candidate(Segment seg, FiberRay fri, ShapedPiece pc, int t, int j, inout ShapedScan sc) {
    gTests++;
    // the rest position turned by the twist at both ends: at P0 in the placement's own cosine and sine
    vec2 turned0 = fiber_rest_turned(pc.A, pc.B, pc.ringKey, pc.ring, j, pc.P0.tau);
    vec2 turned1 = vec2(pc.dTau.x * turned0.x - pc.dTau.y * turned0.y, pc.dTau.y * turned0.x + pc.dTau.x * turned0.y);
    float vEnd = fiber_v_end(pc.A, pc.ringKey, pc.ring, j, sLengthJitter);
    float phase = shaped_curl_phase(pc.ringKey, pc.ring, j);
    int kind;
    float s = piece_entry(seg, fri, pc.P0, pc.P1, pc.invLen, pc.curlStep, turned0, turned1, phase, vEnd, kind);
    s = pc.ring == gSkipRing && j == gSkipFiber ? INF : s;
    bool better = beats(s, pc.ring, j, sc.best.s, sc.best.ring, sc.best.fiber);
    sc.best.s = better ? s : sc.best.s;
    sc.best.ring = better ? pc.ring : sc.best.ring;
    sc.best.fiber = better ? j : sc.best.fiber;
    sc.best.kind = better ? kind : sc.best.kind;
    sc.found = sc.found || better;
    sc.end = !better ? sc.end : (gMode == 0 ? t : min(sc.end, t + 1 + pc.after));   // fast: the first wins
#if SHAPED_POINT_STOP
    // exact: a hit nearer than the best so far lies on this piece's ray before the best's point H (the
    // piece's end while the best lies beyond it). A fiber is hit only where the ray comes within the disc
    // of its rest chord, which lies in the wedge of its rest position turned by the twist at the piece's
    // ends, so where the wedge's first edge along the sweep (the turn at P0 or at P1), turned back by the
    // disc, lies past H (seen from the axis, in theta's order), it and every later slot (the jitter keeps
    // the rest directions in slot order) are hit after H, if at all: the scan stops there. Valid while the
    // angles compared stay within half a turn of each other.
    sc.H = better ? pc.P0.p + ((s - pc.P0.s) * pc.invLen) * (pc.P1.p - pc.P0.p) : sc.H;
    vec2 edge = pc.backAtEnd ? turned1 : turned0;
    vec2 back = vec2(pc.turn.x * edge.x - pc.turn.y * edge.y, pc.turn.y * edge.x + pc.turn.x * edge.y);
    bool beyond = pc.angled && float(pc.dir) * (sc.H.x * back.y - sc.H.y * back.x) > 0.0;
    sc.end = beyond ? min(sc.end, t + 1) : sc.end;
#endif
}

FiberHit traverse_shaped(Segment seg, UnitRay ur) {
    ShapedScan sc;
    sc.best = no_hit();
    FiberRay fr = fiber_ray(seg, ur);
    Bands bands = segment_bands(seg);
    vec2 o2 = ur.O.xy;
    vec2 d2 = ur.D.xy;
    float a2 = dot(d2, d2);
    float sa = sqrt(a2);
    float sMid = a2 > 0.0 ? -dot(o2, d2) / a2 : ur.s0;
    // The bands the path enters (a prefix of the rings: outer radii fall with the ring index) and those
    // of them it crosses twice (a prefix again): a circle of radius r is met when |o x d| <= |d| r.
    float cr = o2.x * d2.y - o2.y * d2.x;          // the ray's angle about the axis turns at cr / |p|^2
    float crs = abs(cr);
    int K = uRings;
    int nReached = 0;
    int nTwice = 0;
    for (int i = 0; i < K; i++) {
        gIters++;
        vec2 band = ring_band(i, bands);
        if (crs > sa * band.y) break;       // and no deeper ring either (a ring crossed twice is met)
        nReached++;
        nTwice += crs <= sa * band.x ? 1 : 0;
    }
    nTwice = min(nTwice, nReached);
    // The arcs of a lane: its fronts and first halves by ring going in (ring p at pass p < m), then its
    // second halves and backs by ring going back out (ring 2m - 1 - p), m = nReached. The second halves all
    // start at the closest approach, so their order is free; going out puts every lane at pass p on a ring
    // no deeper than min(p, 2K - 1 - p), which is what bounds a batch's loop passes with each lane in its
    // own order (renderer.py: needs_ring_order). By ring (uRingOrder): m = K in every lane, so every lane of
    // a SIMD batch visits the same ring at the same pass and each ring at most twice (draw_ranges).
    int m = uRingOrder != 0 ? K : nReached;
    int arcs = 2 * m;
    for (int p = 0; p < arcs; p++) {
        gIters++;
        int i = p < m ? p : arcs - 1 - p;
        int side = p < m ? 0 : (i < nTwice ? 2 : 1);
        bool twice = i < nTwice;
        bool applies = i < nReached && (side == 0 || (side == 1) != twice);
        vec2 band = ring_band(i, bands);
        vec2 outer = circle_interval(o2, d2, vec2(0.0), band.y);
        vec2 inner = circle_interval(o2, d2, vec2(0.0), band.x);
        float sA = side == 0 ? outer.x : (side == 1 ? sMid : inner.y);
        float sB = side == 0 ? (twice ? inner.x : sMid) : outer.y;
        float a = max(sA, ur.s0);
        float b = min(sB, ur.s1);
        bool inside = applies && a <= b;
        // arcs come in order of their start. One that starts at the nearest hit can only tie it (a ray that
        // starts inside fibers of two rings enters both at its start), and the lower ring wins a tie: it is
        // visited if its ring is not above the best's (the arcs after it may still be lower rings)
        // (sKnown: a nearer hit is known elsewhere, traverse.glsl: limit_traversal)
        if (inside && (a > ur.sKnown || (gMode != 2 && a > sc.best.s))) break;
        if (applies && sA > ur.s1) break;           // nor can any later arc reach the stretch
        inside = inside && (gMode == 2 || a < sc.best.s || i <= sc.best.ring);
        Bands arcBands = bands;
#if SHAPE_ELLIPSOID
        // The heights the arc spans bound the ellipsoid's scale tighter than the segment's do: the ring's
        // fibers there lie in a narrower band, which cuts the arc down and narrows the reach. (The break
        // above keeps the segment band's start, which is what comes in order.)
        float va = unit_to_v(seg, ur.O.z + a * ur.D.z);
        float vb = unit_to_v(seg, ur.O.z + b * ur.D.z);
        arcBands.eLo = min(shape_scale(va), shape_scale(vb));
        arcBands.eHi = min(va, vb) <= 0.5 && max(va, vb) >= 0.5 ? 1.0 : max(shape_scale(va), shape_scale(vb));
        vec2 tight = ring_band(i, arcBands);
        vec2 outerT = circle_interval(o2, d2, vec2(0.0), tight.y);
        vec2 innerT = circle_interval(o2, d2, vec2(0.0), tight.x);
        a = max(a, side == 0 ? outerT.x : innerT.y);        // side 0 lies before the closest approach
        b = min(b, side == 0 ? innerT.x : outerT.y);
        inside = inside && a <= b;
#endif
        ivec2 share = ring_share(i, gMode == 2 ? sBruteRange : sFiberRange);
        bool open = inside && share.x < share.y;            // else none of this ring's fibers is in this draw
        gPieces += open ? 1 : 0;
        RingPoint P0 = ring_point(seg, ur, a, i);
        float dvArc = abs(unit_to_v(seg, ur.O.z + b * ur.D.z) - P0.v);
        int pieces = open ? chord_pieces(dvArc, i, arcBands.eLo) : 0;
        float step = (b - a) / float(max(pieces, 1));
        ShapedPiece pc;
        pc.A = uRingA[i];
        pc.B = uRingB[i];
        pc.ringKey = ring_key(sSeed, seg.guide, i);
        pc.ring = i;
        FiberRay fri = fiber_ray_ring(fr, i);           // this ring's fiber radius
        int n = uRingN[i].x;
        sc.found = false;
        pc.P0 = P0;
        // the angle of the piece's start seen from the axis: each piece's end is the next one's start
        float thA = atan(P0.p.y, P0.p.x);
        for (int k = 0; k < pieces; k++) {
            gIters++;
            // the last piece ends at b itself: one ring_point with its parameter chosen (a select of two
            // points would run both, and a piece's point costs a division, a root and, twisted, a sine)
            pc.P1 = ring_point(seg, ur, k == pieces - 1 ? b : a + float(k + 1) * step, i);
            pc.invLen = pc.P1.s > pc.P0.s ? 1.0 / (pc.P1.s - pc.P0.s) : 0.0;
#if SHAPE_CURL != 0
            pc.curlStep = ring_curl_step(pc.P0, pc.P1);
#else
            pc.curlStep = vec2(1.0, 0.0);
#endif
            float dTau = pc.P1.tau - pc.P0.tau;
            pc.dTau = vec2(cos(dTau), sin(dTau));
            // cos(dTau / 2), which bounds how near the axis a rest chord dips (0 past half a turn)
            float chordCos = abs(dTau) < 3.0 ? sqrt(max(0.0, 0.5 + 0.5 * pc.dTau.x)) * (1.0 - EPS_CHORD) : 0.0;
            // the candidates: slots within the reach of the angles the piece sweeps (a straight ray never
            // sweeps half a turn or more: past 2.5 radians with the twist, or so near the axis that the
            // reach is the whole ring, all are taken)
            float rayMin = chord_distance(pc.P0.p, pc.P1.p) * (1.0 - EPS_CHORD);
            float reach = shaped_reach(i, arcBands, rayMin, chordCos);
            // (a point on the axis has no angle: a piece that starts there takes its end's, one that ends
            // there its start's)
            thA = dot(pc.P0.p, pc.P0.p) > 0.0 ? thA : atan(pc.P1.p.y, pc.P1.p.x);
            float thB = dot(pc.P1.p, pc.P1.p) > 0.0 ? atan(pc.P1.p.y, pc.P1.p.x) : thA;
            float spanX = wrap_pi(thB - thA);
            PieceWindow win = piece_window(thA, spanX, pc.P0, pc.P1, cr, rayMin, reach, chordCos);
            float span = win.span;
            int dir = gMode == 2 ? 1 : win.dir;
            pc.dir = dir;
            // exact: a hit nearer than one on candidate t lies before it on the ray, so its fiber's slot
            // is at most win.after further on (traverse_straight's rule: two reaches, and the twist's turn
            // where the window is the box)
            pc.after = gMode == 1 ? int(floor(win.after * pc.B.z * (1.0 + EPS_AFTER))) + 1 : n;
            float first = (win.start - float(dir) * win.reach - pc.A.z) * pc.B.z;
            float last = (win.start + span + float(dir) * win.reach - pc.A.z) * pc.B.z;
#if SHAPED_POINT_STOP
            // exact: the best's point on this piece (shaped_candidate says what stops there), the wedge's
            // first edge along the scan (the lower twist going up, the higher going down)
            float sH = clamp(sc.best.s, pc.P0.s, pc.P1.s);
            sc.H = sH >= pc.P1.s ? pc.P1.p : pc.P0.p + ((sH - pc.P0.s) * pc.invLen) * (pc.P1.p - pc.P0.p);
            pc.angled = gMode == 1 && win.thetaOrder && abs(span) + 2.0 * win.reach < 3.0;
            pc.backAtEnd = (dir > 0) == (dTau < 0.0);
            vec2 turn = shaped_turn(i, arcBands, rayMin, chordCos);
            pc.turn = vec2(turn.x, -float(dir) * turn.y);
#else
            sc.H = vec2(0.0);
            pc.angled = false;
            pc.backAtEnd = false;
            pc.turn = vec2(1.0, 0.0);
#endif
            int j0 = dir > 0 ? int(ceil(first)) : int(floor(first));
            int j1 = dir > 0 ? int(floor(last)) : int(ceil(last));
            int count = abs(span) > 2.5 ? n : min(max(0, (j1 - j0) * dir + 1), n);
            j0 = gMode == 2 ? 0 : j0;
            count = gMode == 2 ? n : count;
            ivec2 run0 = candidate_run(0, j0, dir, count, n, share);
            ivec2 run1 = candidate_run(1, j0, dir, count, n, share);
            sc.end = run0.y + run1.y;
            // The scan's rules (skip, tie order, fast/exact stop) as traverse_straight's: straight.glsl
            // says why the two loops are apart; change both together.
#if SHAPED_SCREEN
            // The window goes in chunks of 32 slots. Fibers that end below the whole piece cannot be hit on
            // it (piece_entry's length cut), and where the piece climbs above 1 - length jitter some of them
            // do: there a cheap pass over the chunk (the length random: two hash rounds) marks the fibers
            // that reach the piece, and only those get the full test. (On the bench's curled scene half of
            // the tests were fibers ending below the ray; for twist or the ellipsoid alone the chunks cost
            // more than they save.) Brute force tests every fiber, as it always did.
            // (piece_entry cuts a fiber only where it ends before the segment does: one that reaches v1 goes on
            // into the joint's wedge, where the ray's height can pass v1)
            float vLow = min(min(pc.P0.v, pc.P1.v) - EPS_V_END, seg.v1);
            bool screen = gMode != 2 && vLow > 1.0 - sLengthJitter;
            for (int t0 = 0; t0 < sc.end; t0 += 32) {
                gIters++;
                int width = min(32, sc.end - t0);
                uint reaches = 0u;
                for (int u = 0; u < (screen ? width : 0); u++) {
                    gIters++;
                    int j = candidate(run0, run1, dir, t0 + u);
                    reaches |= fiber_v_end(pc.A, pc.ringKey, i, j, sLengthJitter) >= vLow ? 1u << u : 0u;
                }
                uint live = screen ? reaches : (width >= 32 ? 0xffffffffu : (1u << width) - 1u);
                while (live != 0u) {
                    gIters++;
                    int t = t0 + findLSB(live);
                    live &= live - 1u;
                    shaped_candidate(seg, fri, pc, t, candidate(run0, run1, dir, t), sc);
                    live = t + 1 >= sc.end ? 0u : live;
                }
            }
#else
            for (int t = 0; t < sc.end; t++) {
                gIters++;
                shaped_candidate(seg, fri, pc, t, candidate(run0, run1, dir, t), sc);
            }
#endif
            // exact: no later piece can start before the nearest hit; fast: stop at the first; none
            // past a hit known elsewhere
            bool stop = (gMode == 0 ? sc.found : (gMode == 1 && pc.P1.s >= sc.best.s)) || pc.P1.s >= ur.sKnown;
            pieces = stop ? k + 1 : pieces;
            pc.P0 = pc.P1;
            thA = thB;
        }
        if (gMode == 0 && sc.found) break;
    }
    // the hit fiber's centre and how it moves with v, in the container's frame, for shading. Its rest
    // position and curl phase are placed again here rather than carried through the scan: every value a
    // loop carries costs a select and a blend on every pass
    FiberHit best = sc.best;
    bool hit = best.s < INF;
    int ringHit = max(best.ring, 0);
    int fiberHit = max(best.fiber, 0);
    uint keyHit = ring_key(sSeed, seg.guide, ringHit);
    vec2 rest;
    float vEndUnused;
    fiber_center_keyed(uRingA[ringHit], uRingB[ringHit], keyHit, ringHit, fiberHit, rest, vEndUnused);
    rest = hit ? rest : vec2(0.0);
    float phase = hit ? shaped_curl_phase(keyHit, ringHit, fiberHit) : 0.0;
    float v = unit_to_v(seg, ur.O.z + (hit ? best.s : 0.0) * ur.D.z);
    best.c = fiber_center_at(rest, v, ringHit, phase);
    best.dcdv = (fiber_center_at(rest, v + DCDV_STEP, ringHit, phase)
               - fiber_center_at(rest, v - DCDV_STEP, ringHit, phase)) / (2.0 * DCDV_STEP);
    return best;
}

#endif
