// intervals.glsl: ray intervals inside simple regions, as vec2(tEnter, tExit); empty when x > y.
//   vec2 circle_interval(vec2 o, vec2 d, vec2 c, float r)   infinite vertical cylinder, radius r about c
//   vec2 radius_interval(float a, float b, float len, float crs, float r)   its roots, for any dimension
//   vec2 slab(float o, float d, float lo, float hi)           lo <= o + t d <= hi
// Twin: app/reference.py (circle_interval, _slab).

#include "common/epsilon.glsl"

#ifndef GEOMETRY_INTERVALS_GLSL
#define GEOMETRY_INTERVALS_GLSL

// Stable roots (pbrt): q = -(b + sign(b) sqrt(disc)), t0 = q / a, t1 = c / q, with the discriminant
// a r^2 - cross^2 factored as (sqrt(a) r - |cross|)(sqrt(a) r + |cross|) so it never cancels. A ray
// parallel to the axis (a = 0) is inside for every t or for none.
// Written without early returns: llvmpipe runs both sides of every branch anyway, and code after a
// return becomes a masked block whose every assignment costs a blend.
// The roots of a |d|^2 t^2 + 2 b t + |oc|^2 - r^2 = 0 for a ray o + t d about an axis, from a = |d|^2,
// b = oc . d, len = |oc| and crs = |oc x d| (2D or 3D): the interval inside radius r.
vec2 radius_interval(float a, float b, float len, float crs, float r) {
    float cc = (len - r) * (len + r);
    float ra = sqrt(a) * r;
    float disc = (ra - crs) * (ra + crs);
    float q = -(b + (b >= 0.0 ? 1.0 : -1.0) * sqrt(max(disc, 0.0)));
    float ta = q / a;
    float tb = q != 0.0 ? cc / q : ta;
    vec2 along = cc <= 0.0 ? vec2(-INF, INF) : vec2(INF, -INF);    // parallel to the axis
    return a == 0.0 ? along : (disc < 0.0 ? vec2(INF, -INF) : vec2(min(ta, tb), max(ta, tb)));
}

vec2 circle_interval(vec2 o, vec2 d, vec2 c, float r) {
    vec2 oc = o - c;
    return radius_interval(dot(d, d), dot(oc, d), length(oc), abs(oc.x * d.y - oc.y * d.x), r);
}

vec2 slab(float o, float d, float lo, float hi) {
    float ta = (lo - o) / d;
    float tb = (hi - o) / d;
    vec2 along = (o >= lo && o <= hi) ? vec2(-INF, INF) : vec2(INF, -INF);    // d == 0
    return d == 0.0 ? along : vec2(min(ta, tb), max(ta, tb));
}

#endif
