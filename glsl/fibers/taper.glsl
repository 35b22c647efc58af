// taper.glsl: tip taper, each fiber thinning toward its own tip (issue 15), in unit space.
//   vec2  taper_line(float v0, float v1, float zScale, float r0, float kappa, float vEnd)
//                       (l0, l1): the fiber's width over the segment is uFiberRadius * min(1, l0 + l1 Z)
//   float taper_apex(vec2 line)                 unit height where the width reaches 0 (INF: no thinning)
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

// zScale = h / (v1 - v0) turns guide parameter into local height zeta (the segment's FiberRay holds it).
// The chord's slope in Z comes from the slope in v times (v_b - v_a) / (Z_b - Z_a), which for
// Z = zeta / (r0 + kappa zeta) is w_a w_b / (r0 zScale): no difference of nearby heights.
vec2 taper_line(float v0, float v1, float zScale, float r0, float kappa, float vEnd) {
    float vS = uTaperStart * vEnd;
    float dgdv = -(1.0 - uTipWidth) / max((1.0 - uTaperStart) * vEnd, EPS_DIVISOR);
    float vA = clamp(vS, v0, v1);
    float vB = min(vEnd, v1);
    float gA = 1.0 + dgdv * max(0.0, vA - vS);
    float zetaA = (vA - v0) * zScale;
    float wA = r0 + kappa * zetaA;
    float wB = r0 + kappa * (vB - v0) * zScale;
    float l1 = vA < vB ? dgdv * wA * wB / (r0 * zScale) : 0.0;
    return vec2(gA - l1 * (zetaA / wA), l1);
}

float taper_apex(vec2 line) {
    return line.y < 0.0 ? -line.x / line.y : INF;
}

// f(t) = |oc + t d|^2 - (rho0 + rho1 t)^2 = a t^2 + 2 b t + c, a = |d|^2 - rho1^2. A ray shallower than
// the cone's side (a > 0) is inside between the roots; a steeper one (a < 0) outside them, of which only
// the half toward the widening side is this nappe (the caller cuts at the apex: taper_apex); a = 0, the
// ray parallel to a side line, has one root. Roots as intervals.glsl's, the discriminant factored:
// b^2 - a c = |rho0 d - rho1 oc|^2 - |oc x d|^2, which for rho1 = 0 is the cylinder's.
vec2 cone_interval(vec2 oc, vec2 d, float rho0, float rho1) {
    float dl = length(d);
    float ar = abs(rho1);
    float a = (dl - ar) * (dl + ar);
    float b = dot(oc, d) - rho0 * rho1;
    float len = length(oc);
    float c = (len - rho0) * (len + rho0);
    float crs = abs(oc.x * d.y - oc.y * d.x);
    float m = length(rho0 * d - rho1 * oc);
    float disc = (m - crs) * (m + crs);
    float q = -(b + (b >= 0.0 ? 1.0 : -1.0) * sqrt(max(disc, 0.0)));
    float ta = q / (a != 0.0 ? a : 1.0);
    float tb = q != 0.0 ? c / q : ta;
    vec2 roots = vec2(min(ta, tb), max(ta, tb));
    vec2 shallow = disc >= 0.0 ? roots : vec2(INF, -INF);
    vec2 steep = rho1 > 0.0 ? vec2(roots.y, INF) : vec2(-INF, roots.x);
    vec2 level = b > 0.0 ? vec2(-INF, tb) : (b < 0.0 ? vec2(tb, INF)
               : (c <= 0.0 ? vec2(-INF, INF) : vec2(INF, -INF)));
    return a > 0.0 ? shallow : (a < 0.0 ? steep : level);
}

// The side normal of a fiber in the container's local frame is the gradient of |P.xy - c|^2 - rho(Z)^2
// through the unit-space map: (radial, -kappa radial . P.xy - rho rho'(Z) (1 - kappa Z)), rho the radius
// at the hit (|radial|), slope = rho'(Z) = fiber radius * l1; this returns the last term. (The centre's
// own motion with Z, for curved fibers, is left out as for the untapered side.)
float taper_normal_z(float slope, float rho, float z, float kappa) {
    return -rho * slope * (1.0 - kappa * z);
}

#endif  // FIBERS_TAPER_GLSL
