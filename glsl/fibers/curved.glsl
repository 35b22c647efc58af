// curved.glsl: a ray against curved fibers (curl, twist, ellipsoid), piece by piece.
//   int   chord_pieces(float dv, int ring, float eLo)   pieces for one arc of the ray
//   float piece_entry(Segment seg, FiberRay fr, RingPoint P0, RingPoint P1, float invLen, vec2 curlStep,
//                     vec2 turned0, vec2 turned1, float curlPhase, float vEnd, out int kind)
// A curved fiber is the set of points whose horizontal (unit-space) distance to its centre line c(v) is
// at most fiber_radius. An arc of the ray (the stretch inside one ring's band) is cut into pieces, the
// same pieces for every fiber of the ring; on a piece the fiber stands for the chord between its centres
// at the piece's two ends (fiber_center_at, shape.glsl), in the container's frame, where the ray is
// straight: the ray seen from the fiber is a point moving on a line, and the test is the stable quadratic
// of a straight fiber. The result depends only on (ray, ring, arc, fiber), never on the traversal mode,
// so exact equals brute. (The candidates are chosen in the frame that turns with the twist, shaped.glsl.)
// Chord rule: the fiber's centre c(v(s)) stays within a tenth of a fiber radius of its chord when a piece
// climbs no more than dv = sqrt(0.8 r / |c''(v)|) (r the fiber radius; |c''| bounds the bend the twist,
// the curl, the frizz and the ellipsoid give the centre line): a ray across the fibers (dv near 0) needs
// one piece, a ray along them up to MAX_SUB. The ray itself is straight in this frame, so its sweep
// about the axis bends nothing (in the turning frame it would: the twist's Coriolis term, which cut
// every shallow ray across a twisted ring into pieces).
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

// Pieces for an arc that climbs dv in guide parameter. Per unit v, with tau' and tau'' the twist's rates,
// rho the ring's outer rest radius and E >= max(eLo, 1/4) (as the test has always assumed):
//   |c''| <= rho (tau'^2 + tau'' + |E''| + 2 |E'| tau') + curl'',  |E''| <= 4 e^2 / E^3, |E'| <= 2 e^2 / E,
// curl'' = A (2 pi F)^2 for the helix (it turns at its own rate in this frame), and for what sways along a
// direction that turns with the twist (the wave, frizz, noise) amplitude ((2 pi f + tau')^2 + tau''),
// f its frequency (the frizz's strays up to half of frizz from the curl's).
int chord_pieces(float dv, int ring, float eLo) {
    float rho = uRingA[ring].x + uRingB[ring].x;
    float rate = TWO_PI * sTwistAbs * (sTwistPattern == TWIST_RAMPED ? 2.0 : 1.0);
    float rate2 = sTwistPattern == TWIST_RAMPED ? 2.0 * TWO_PI * sTwistAbs : 0.0;
    float f = TWO_PI * sCurlFrequency;
    float fw = f + rate;
    float curl = sCurlAmplitude * (sCurlPattern == CURL_HELIX ? f * f : fw * fw + rate2);
    float fz = TWO_PI * sCurlFrequency * (1.0 + 0.5 * sFrizz) + rate, fn = TWO_PI * sNoiseFrequency + rate;
    curl = curl + sFrizzAmplitude * (fz * fz + rate2) + sNoiseAmplitude * (fn * fn + rate2);
    float e = max(eLo, 0.25);
    float e2 = 4.0 * sEllipsoid * sEllipsoid;
    float bendV = rho * (rate * rate + rate2 + e2 / (e * e * e) + e2 * rate / e) + curl;
    float n = ceil(sqrt(dv * dv * bendV / (0.8 * max(sFiberRadius, EPS_DIVISOR))));
    return int(clamp(n, 1.0, float(MAX_SUB)));
}

// Entry parameter of the ray into one fiber over the piece [P0.s, P1.s], INF on a miss; kind: 0 the
// fiber's side, 1 its tip (length cut), 2 the piece's start (the ray was inside the fiber there), 3 the
// side of its tapered part (TAPER). turned0 and turned1: the fiber's rest position turned by the ring's
// twist at P0 and at P1 (R(tau) rest).
// The length cut as traverse.glsl's fiber_entry places it, with the ray's reciprocals (FiberRay); invLen
// is 1 / the piece's length, 0 for a piece of no length (the test is then whether P0 is inside).
float piece_entry(Segment seg, FiberRay fr, RingPoint P0, RingPoint P1, float invLen, vec2 curlStep,
                  vec2 turned0, vec2 turned1, float curlPhase, float vEnd, out int kind) {
    float z = (vEnd - seg.v0) * fr.zScale;
    float zc = vEnd >= seg.v1 ? INF : z / (seg.r0 + seg.kappa * z);
    float zt = (zc - fr.oz) * fr.invDz;
    vec2 zs = fr.dz > 0.0 ? vec2(-INF, zt) : (fr.dz < 0.0 ? vec2(zt, INF)
            : (fr.oz <= zc ? vec2(-INF, INF) : vec2(INF, -INF)));
    float lo = max(P0.s, zs.x);
    float hi = min(P1.s, zs.y);
#if SHAPE_CURL != 0
    vec2 curl0 = curl_turn(curlPhase, P0);
    vec2 curl1 = curl_advance(curl0, curlStep);
#else
    vec2 curl0 = vec2(1.0, 0.0), curl1 = vec2(1.0, 0.0);
#endif
    vec2 q0 = P0.p - piece_center(turned0, curl0, P0);
    vec2 q1 = P1.p - piece_center(turned1, curl1, P1);
#if SHAPE_FRIZZ
    // each fiber its own frequency: both ends take their own sine (no shared advance as for the curl),
    // turned by the ring's twist there
    Frizz fz = frizz_of(curlPhase);
    vec2 f0 = frizz_offset(fz, P0.v), f1 = frizz_offset(fz, P1.v);
    q0 -= vec2(P0.cs.x * f0.x - P0.cs.y * f0.y, P0.cs.y * f0.x + P0.cs.x * f0.y);
    q1 -= vec2(P1.cs.x * f1.x - P1.cs.y * f1.y, P1.cs.y * f1.x + P1.cs.x * f1.y);
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
