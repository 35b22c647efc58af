// curved.glsl: a ray against curved fibers (curl, twist, ellipsoid), piece by piece, in the ring's frame.
//   int   chord_pieces(float L, float dv, float sa, int ring, float eLo)   pieces for one arc of the ray
//   float piece_entry(Segment seg, FiberRay fr, RingPoint P0, RingPoint P1, float invLen, vec4 curlStep,
//                     vec2 rest, float curlPhase, float vEnd, out int kind)
// A curved fiber is the set of points whose horizontal (unit-space) distance to its centre line c(v) is
// at most fiber_radius. The traversal looks at the ray in the frame that turns with the ring's twist
// (shape.glsl): there a twisted fiber is straight and the ray turns about the axis instead. An arc of the
// ray (the stretch inside one ring's band) is cut into pieces, the same pieces for every fiber of the
// ring: within a piece the ray's point p(s) and the fiber's centre c'(v(s)) both run along their chords,
// so the ray seen from the fiber is a point moving on a line and the test is the stable quadratic of a
// straight fiber. The result depends only on (ray, ring, arc, fiber), never on the traversal mode, so
// exact equals brute.
// Chord rule: the ray seen from the fiber, q(s) = p(s) - c'(v(s)), stays within a tenth of a fiber radius
// of its chord when a piece is no longer than sqrt(0.8 r / |q''|); |q''| is bounded from the ray's rate
// of climb, dv/ds, which is what makes the rotation, the curl and the ellipsoid bend: a ray across the
// fibers (dv/ds near 0) needs one piece, a ray along them up to MAX_SUB.
// Twin: app/reference.py (chord_pieces, piece_entry).

#include "common/epsilon.glsl"
#include "geometry/intervals.glsl"
#include "fibers/taper.glsl"
#include "geometry/container.glsl"
#include "fibers/layout.glsl"
#include "fibers/fiber_entry.glsl"
#include "fibers/shape.glsl"

#ifndef FIBERS_CURVED_GLSL
#define FIBERS_CURVED_GLSL

#ifndef MAX_SUB
#define MAX_SUB 16
#endif

// the fiber radius as the traversal's loops read it (shape.glsl says why a copy)
float sFiberRadius = abs(uFiberRadius);

// Pieces for an arc of length L (ray parameter) that climbs dv in guide parameter; sa = |D.xy|.
// With w = dv / L:  |q''| <= w^2 (r (tau'^2 + tau'') + rho E'' + curl'') + 2 tau' w sa, where r bounds the
// ray's distance to the axis on the arc, tau' and tau'' the twist's rates (per unit v), rho E'' the
// ellipsoid's bend (E >= max(eLo, 1/4), as the test has always assumed) and curl'' the curl's.
int chord_pieces(float L, float dv, float sa, int ring, float eLo) {
    float rho = uRingA[ring].x + uRingB[ring].x;
    float r = rho + sFiberRadius + shape_displacement();
    float rate = TWO_PI * sTwistAbs * (sTwistPattern == TWIST_RAMPED ? 2.0 : 1.0);
    float rate2 = sTwistPattern == TWIST_RAMPED ? 2.0 * TWO_PI * sTwistAbs : 0.0;
    float f = TWO_PI * sCurlFrequency;
    float curl = sCurlAmplitude * (sCurlPattern == CURL_HELIX ? (f + rate) * (f + rate) + rate2 : f * f);
    // frizz and noise sway along directions fixed in the ring's frame, as the wave: amplitude times the
    // square of the fastest angular rate (the frizz's frequency strays up to half of frizz from the curl's)
    float fz = TWO_PI * sCurlFrequency * (1.0 + 0.5 * sFrizz), fn = TWO_PI * sNoiseFrequency;
    curl = curl + sFrizzAmplitude * fz * fz + sNoiseAmplitude * fn * fn;
    float ell = rho * 4.0 * sEllipsoid * sEllipsoid / (max(eLo, 0.25) * max(eLo, 0.25) * max(eLo, 0.25));
    float bendV = r * (rate * rate + rate2) + ell + curl;
    // L^2 |q''| without dividing by L
    float bendL = dv * dv * bendV + 2.0 * rate * dv * L * sa;
    float n = ceil(sqrt(bendL / (0.8 * max(sFiberRadius, EPS_DIVISOR))));
    return int(clamp(n, 1.0, float(MAX_SUB)));
}

// Entry parameter of the ray into one fiber over the piece [P0.s, P1.s], INF on a miss; kind: 0 the
// fiber's side, 1 its tip (length cut), 2 the piece's start (the ray was inside the fiber there), 3 the
// side of its tapered part (TAPER).
// The length cut as traverse.glsl's fiber_entry places it, with the ray's reciprocals (FiberRay); invLen
// is 1 / the piece's length, 0 for a piece of no length (the test is then whether P0 is inside).
float piece_entry(Segment seg, FiberRay fr, RingPoint P0, RingPoint P1, float invLen, vec4 curlStep,
                  vec2 rest, float curlPhase, float vEnd, out int kind) {
    float z = (vEnd - seg.v0) * fr.zScale;
    float zc = vEnd >= seg.v1 ? INF : z / (seg.r0 + seg.kappa * z);
    float zt = (zc - fr.oz) * fr.invDz;
    vec2 zs = fr.dz > 0.0 ? vec2(-INF, zt) : (fr.dz < 0.0 ? vec2(zt, INF)
            : (fr.oz <= zc ? vec2(-INF, INF) : vec2(INF, -INF)));
    float lo = max(P0.s, zs.x);
    float hi = min(P1.s, zs.y);
#if SHAPE_CURL != 0
    CurlTurn curl0 = curl_turn(curlPhase, P0);
    CurlTurn curl1 = curl_advance(curl0, curlStep);
#else
    CurlTurn curl0, curl1;
#endif
    vec2 q0 = P0.p - ring_frame_center(rest, curl0, P0);
    vec2 q1 = P1.p - ring_frame_center(rest, curl1, P1);
#if SHAPE_FRIZZ
    // each fiber its own frequency: both ends take their own sine (no shared advance as for the curl)
    Frizz fz = frizz_of(curlPhase);
    q0 -= frizz_offset(fz, P0.v);
    q1 -= frizz_offset(fz, P1.v);
#endif
    vec2 dq = (q1 - q0) * invLen;
    vec2 e = circle_interval(q0, dq, vec2(0.0), fr.rf);          // the ring's fiber radius (fiber_ray_ring)
#if TAPER
    // the tapered part: a cone about the moving centre, its radius linear along the piece as in height
    vec2 line = taper_line(fr.ts, vEnd);
    float rho0 = fr.rf * (line.x + line.y * (fr.oz + P0.s * fr.dz));
    vec2 cone = cone_interval(q0, dq, rho0, fr.rf * line.y * fr.dz);
    float sIn = max(max(P0.s + e.x, P0.s + cone.x), lo);
    float sOut = min(min(P0.s + e.y, P0.s + cone.y), hi);
    kind = sIn == P0.s + e.x ? 0 : (sIn == P0.s + cone.x ? 3 : (sIn == zs.x ? 1 : 2));
#else
    float sIn = max(P0.s + e.x, lo);
    float sOut = min(P0.s + e.y, hi);
    kind = sIn == P0.s + e.x ? 0 : (sIn == zs.x ? 1 : 2);
#endif
    return vEnd > seg.v0 && sIn <= sOut ? sIn : INF;
}

#endif
