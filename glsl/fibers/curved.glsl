// curved.glsl: ray against one curved fiber (curl, twist, ellipsoid) over one arc of the ray.
//   float curved_fiber_test(Segment seg, UnitRay ur, vec2 rest, float curlPhase, int ring, float vEnd,
//                           float sA, float sB, out int kind)
// A curved fiber is the set of points whose horizontal (unit-space) distance to its centre line c(v) is
// at most fiber_radius. Over the arc [sA, sB] (where the ray is inside the fiber's ring band) the ray's
// height runs over [va, vb]; that stretch is cut into n pieces short enough that the centre line is
// within a tenth of a fiber radius of its chord, and each piece is solved exactly against the chord (a
// moving circle: the same stable quadratic as a straight fiber). The first piece with a hit wins.
// The result depends only on (ray, fiber, arc), never on the traversal mode, so exact equals brute.
// Twin: app/reference.py (curved_fiber_test).

#include "fibers/shape.glsl"

#ifndef MAX_SUB
#define MAX_SUB 16
#endif

// Chord pieces needed over a height span dv so the chord stays within 0.1 fiber radius of the curve.
int chord_pieces(float dv, int ring, float eLo) {
    float rho = uRingA[ring].x + uRingB[ring].x;
    float curl = uCurlAmplitude * pow(TWO_PI * uCurlFrequency, 2.0);
    float twistRate = TWO_PI * abs(uTwist) * (uTwistPattern == 1 ? 2.0 : 1.0);
    float twist = rho * twistRate * twistRate;
    float ell = rho * 4.0 * uEllipsoid * uEllipsoid / pow(max(eLo, 0.25), 3.0);
    float bend = curl + twist + ell;          // a bound on |c''(v)|
    if (bend <= 0.0) return 1;
    float dvMax = sqrt(0.8 * max(uFiberRadius, 1e-30) / bend);
    return clamp(int(ceil(dv / dvMax)), 1, MAX_SUB);
}

float curved_fiber_test(Segment seg, UnitRay ur, vec2 rest, float curlPhase, int ring, float vEnd,
                        float eLo, float sA, float sB, out int kind) {
    gTests++;
    kind = 0;
    float zc = z_cut_unit(seg, vEnd);
    if (zc == -INF) return INF;
    vec2 zs = slab(ur.O.z, ur.D.z, -INF, zc);
    float a = max(max(sA, ur.s0), zs.x);
    float b = min(min(sB, ur.s1), zs.y);
    if (!(a <= b)) return INF;
    float va = unit_to_v(seg, ur.O.z + a * ur.D.z);
    float vb = unit_to_v(seg, ur.O.z + b * ur.D.z);
    int n = chord_pieces(abs(vb - va), ring, eLo);
    float step = (b - a) / float(n);
    vec2 cPrev = fiber_center_at(rest, va, ring, curlPhase);
    for (int k = 0; k < n; k++) {
        gIters++;
        float sk = a + float(k) * step;
        float sk1 = k == n - 1 ? b : sk + step;
        vec2 cNext = fiber_center_at(rest, unit_to_v(seg, ur.O.z + sk1 * ur.D.z), ring, curlPhase);
        float len = sk1 - sk;
        // the ray seen from the fiber's chord: a point moving at D.xy - (chord velocity)
        vec2 q0 = ur.O.xy + sk * ur.D.xy - cPrev;
        vec2 dq = len > 0.0 ? ur.D.xy - (cNext - cPrev) / len : ur.D.xy;
        vec2 e = circle_interval(q0, dq, vec2(0.0), uFiberRadius);
        float lo = max(e.x, 0.0);
        float hi = min(e.y, len);
        if (lo <= hi) {
            if (k == 0 && lo == 0.0) kind = a == zs.x ? 1 : 2;   // entered through the tip or a boundary
            return sk + lo;
        }
        cPrev = cNext;
    }
    return INF;
}
