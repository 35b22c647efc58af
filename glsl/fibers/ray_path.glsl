// ray_path.glsl: the ray's path across the rings, seen along the container's axis.
//   RayPath ray_path(UnitRay ur)
//   float   path_s(RayPath rp, float x)              ray parameter at path position x
//   float   boundary_radius(int k)                   radius of ring boundary k (0: the wall)
//   vec2    boundary_crossing(RayPath rp, int k)     (h, psi) where the path crosses boundary k
//   int     deepest_ring(RayPath rp)                 the ring that holds the path's closest approach
// An "arc" is the stretch of the ray's path (in the unit-space xy plane) inside one ring's annulus. The
// path crosses a ring twice (front and back arc) or, for the deepest ring it reaches, once; that stretch is
// split at the point closest to the axis so each piece sweeps less than 90 degrees.

#include "common/epsilon.glsl"
#include "geometry/container.glsl"
#include "fibers/layout.glsl"

#ifndef FIBERS_RAY_PATH_GLSL
#define FIBERS_RAY_PATH_GLSL

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

#endif
