// taper.glsl: tip taper, each fiber thinning toward its own tip (issue 15), in unit space.
//   TaperSeg taper_seg(float v0, float v1, float zScale, float r0, float kappa)   a segment's share
//   vec2  taper_line(TaperSeg ts, float vEnd)   (l0, l1): the fiber's width over the segment is
//                                               uFiberRadius * min(1, l0 + l1 Z), Z the unit height
//   float taper_apex(vec2 line)                 unit height where the width reaches 0 (INF: no thinning)
//   vec2  cone_roots(float a, float b, float c, float disc, float rho0, float rho1)   from its terms
//   vec2  cone_interval(vec2 oc, vec2 d, float rho0, float rho1)   ray interval in |oc + t d| <= rho0 + rho1 t
//   float taper_normal_z(float slope, float rho, float z, float kappa)  what the cone adds to a side normal
// Along its own length (guide parameter v, 0 at the root, vEnd at its tip) a fiber's width is 1 up to
// v_s = uTaperStart * vEnd, then falls linearly to uTipWidth at vEnd. Within one segment the width is kept
// linear in the unit-space height Z, through the exact values at the two ends of the segment's thinning
// part: the tapering part is then a cone, which a ray meets in one quadratic, and the fiber is the
// root-width cylinder cut by it (both convex: the ray's interval in the fiber is the intersection of its
// intervals in each, never wider than the cylinder's, so every traversal bound holds).
// Built in only with TAPER 1 (renderer.py: model_defines), so tip width 1 leaves today's shader as it was.
// Twin: app/fibers/taper.py (taper_line, taper_apex), app/reference.py (cone_interval);
// OSL: osl/fibers/taper.osl. docs/shaped-traversal.md, "Tip taper".

#include "common/epsilon.glsl"

#ifndef FIBERS_TAPER_GLSL
#define FIBERS_TAPER_GLSL

#ifndef TAPER
#define TAPER 0
#endif

uniform float uTipWidth;        // width at the fiber's own tip / its root width
uniform float uTaperStart;      // fraction of the fiber's length where it starts to thin

// What the width lines of one segment's fibers share (a traversal makes it once per ray).
struct TaperSeg {
    float v0, v1;
    float zScale;   // guide parameter -> local height, h / (v1 - v0)
    float r0, kappa;
    float fall;     // dg/dv times the fiber's length: -(1 - tip width) / (1 - taper start)
    float invR0z;   // 1 / (r0 zScale)
};

TaperSeg taper_seg(float v0, float v1, float zScale, float r0, float kappa) {
    TaperSeg ts;
    ts.v0 = v0;
    ts.v1 = v1;
    ts.zScale = zScale;
    ts.r0 = r0;
    ts.kappa = kappa;
    ts.fall = -(1.0 - uTipWidth) / max(1.0 - uTaperStart, EPS_DIVISOR);
    ts.invR0z = 1.0 / (r0 * zScale);
    return ts;
}

// The chord's slope in Z comes from the slope in v times (v_b - v_a) / (Z_b - Z_a), which for
// Z = zeta / (r0 + kappa zeta) is w_a w_b / (r0 zScale): no difference of nearby heights. One division
// gives both 1 / vEnd and 1 / w_a.
vec2 taper_line(TaperSeg ts, float vEnd) {
    float vS = uTaperStart * vEnd;
    float vA = clamp(vS, ts.v0, ts.v1);
    float vB = min(vEnd, ts.v1);
    float zetaA = (vA - ts.v0) * ts.zScale;
    float wA = ts.r0 + ts.kappa * zetaA;
    float wB = wA + ts.kappa * (vB - vA) * ts.zScale;
    float end = max(vEnd, EPS_DIVISOR);
    float inv = 1.0 / (end * wA);
    float dgdv = ts.fall * wA * inv;
    float gA = 1.0 + dgdv * max(0.0, vA - vS);
    float l1 = vA < vB ? dgdv * wA * wB * ts.invR0z : 0.0;
    return vec2(gA - l1 * zetaA * end * inv, l1);
}

float taper_apex(vec2 line) {
    return line.y < 0.0 ? -line.x / line.y : INF;
}

// The interval of t where f(t) = a t^2 + 2 b t + c <= 0 and the radius rho0 + rho1 t is positive, from
// the discriminant disc = b^2 - a c: for a cone, f(t) = |oc + t d|^2 - (rho0 + rho1 t)^2, a = |d|^2 - rho1^2.
// A ray shallower than the cone's side (a > 0) is inside between the roots, on this nappe if the radius
// is positive between them (else it crossed the mirror nappe past the apex); a steeper one (a < 0) outside
// them, and only the half toward the widening side is this nappe, all of it; a = 0, the ray parallel to a
// side line, has one root, on this nappe where the radius there is positive. Roots as intervals.glsl's.
vec2 cone_roots(float a, float b, float c, float disc, float rho0, float rho1) {
    float q = -(b + (b >= 0.0 ? 1.0 : -1.0) * sqrt(max(disc, 0.0)));
    float ta = q / (a != 0.0 ? a : 1.0);
    float tb = q != 0.0 ? c / q : ta;
    vec2 roots = vec2(min(ta, tb), max(ta, tb));
    bool near = disc >= 0.0 && rho0 + rho1 * 0.5 * (roots.x + roots.y) >= 0.0;
    vec2 shallow = near ? roots : vec2(INF, -INF);
    vec2 steep = rho1 > 0.0 ? vec2(roots.y, INF) : vec2(-INF, roots.x);
    vec2 level = rho0 + rho1 * tb < 0.0 ? vec2(INF, -INF) : (b > 0.0 ? vec2(-INF, tb) : (b < 0.0 ? vec2(tb, INF)
               : (c <= 0.0 ? vec2(-INF, INF) : vec2(INF, -INF))));
    return a > 0.0 ? shallow : (a < 0.0 ? steep : level);
}

// The ray oc + t d (relative to the axis) in the cone of radius rho0 + rho1 t: the discriminant factored,
// b^2 - a c = |rho0 d - rho1 oc|^2 - |oc x d|^2, which for rho1 = 0 is the cylinder's.
vec2 cone_interval(vec2 oc, vec2 d, float rho0, float rho1) {
    float dl = length(d);
    float ar = abs(rho1);
    float len = length(oc);
    float crs = abs(oc.x * d.y - oc.y * d.x);
    float m = length(rho0 * d - rho1 * oc);
    return cone_roots((dl - ar) * (dl + ar), dot(oc, d) - rho0 * rho1, (len - rho0) * (len + rho0),
                      (m - crs) * (m + crs), rho0, rho1);
}

// The side normal of a fiber in the container's local frame is the gradient of |P.xy - c|^2 - rho(Z)^2
// through the unit-space map: (radial, -kappa radial . P.xy - rho rho'(Z) (1 - kappa Z)), rho the radius
// at the hit (|radial|), slope = rho'(Z) = fiber radius * l1; this returns the last term. (The centre's
// own motion with Z, for curved fibers, is left out as for the untapered side.)
float taper_normal_z(float slope, float rho, float z, float kappa) {
    return -rho * slope * (1.0 - kappa * z);
}

#endif  // FIBERS_TAPER_GLSL
