// fiber_entry.glsl: one ray against one straight fiber of a container.
//   FiberRay fiber_ray(Segment seg, UnitRay ur)      what every fiber test of one ray shares
//   float    fiber_entry(Segment seg, FiberRay fr, vec2 c, float vEnd, out int kind)   entry s or INF
//   FiberRay fiber_ray_ring(FiberRay fr, int i)       the same for the fibers of ring i (their radius)

#include "common/epsilon.glsl"
#include "geometry/container.glsl"
#include "fibers/layout.glsl"
#include "fibers/taper.glsl"

#ifndef FIBERS_FIBER_ENTRY_GLSL
#define FIBERS_FIBER_ENTRY_GLSL

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
#if TAPER
    float sa;       // |D.xy|
    TaperSeg ts;    // what the fibers' width lines share (taper.glsl)
#endif
    float rf;       // fiber radius (fiber_ray_ring: the ring's)
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
#if TAPER
    fr.sa = sqrt(a);
    fr.ts = taper_seg(seg.v0, seg.v1, fr.zScale, seg.r0, seg.kappa);
#endif
    fr.rf = uFiberRadius;
    return fr;
}

// One fiber: a capped vertical cylinder of radius uFiberRadius about c, from the container's root plane
// to the fiber's length cut at guide parameter vEnd, inside the container interval [s0, s1]. Returns the
// entry parameter or INF; kind: 0 through the fiber's side, 1 its tip, 2 a container boundary, 3 the
// side of its tapered part (TAPER: the cylinder cut by the cone of taper.glsl, ending at its apex).
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
#if TAPER
    // the radius is linear in the height, so along the ray too: rho0 + rho1 s; the cone's terms from the
    // cylinder's (taper.glsl: cone_interval)
    vec2 line = taper_line(fr.ts, vEnd);
    float rho0 = fr.rf * (line.x + line.y * fr.oz);      // fr.rf: the ring's radius (fiber_ray_ring)
    float rho1 = fr.rf * line.y * fr.dz;
    float ar = abs(rho1);
    float m = length(rho0 * fr.d2 - rho1 * oc);
    vec2 cone = cone_roots((fr.sa - ar) * (fr.sa + ar), b - rho0 * rho1, cc + (fr.rf - rho0) * (fr.rf + rho0),
                           (m - crs) * (m + crs), rho0, rho1);
    float sIn = max(max(max(cyl.x, cone.x), zr.x), fr.s0);
    float sOut = min(min(min(cyl.y, cone.y), zr.y), fr.s1);
    kind = sIn == cyl.x ? 0 : (sIn == cone.x ? 3 : (sIn == zr.x ? 1 : 2));
#else
    float sIn = max(max(cyl.x, zr.x), fr.s0);
    float sOut = min(min(cyl.y, zr.y), fr.s1);
    kind = sIn == cyl.x ? 0 : (sIn == zr.x ? 1 : 2);
#endif
    bool hit = disc >= 0.0 && sIn <= sOut && vEnd > seg.v0;
    return hit ? sIn : INF;
}

// The fiber terms of a ray for the fibers of ring i, whose radius the clump profile may thin
// (app/fibers/layout.py: RingLayout.ring_radius); the same expressions as fiber_ray, so a ring at the
// core's radius gives the same bits.
FiberRay fiber_ray_ring(FiberRay fr, int i) {
    float r = uRingRadius[i];
    fr.ra = sqrt(dot(fr.d2, fr.d2)) * r;
    fr.rf2 = r * r;
    fr.rf = r;
    return fr;
}

#endif
