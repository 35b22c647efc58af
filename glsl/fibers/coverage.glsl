// coverage.glsl: the filtered mode (quality.filter = coverage, FILTER 1): a pixel's ray is a cone, and
// every fiber of a container contributes the share of the cone's footprint it covers.
//   float footprint_coverage(float x, float r, float w)   share of a tent footprint a fiber covers
//   bool  to_unit_space_dilated(Segment seg, vec3 rd, float tNear, out UnitRay ur, out float wu)
//   CoverBlend cover_straight(Segment seg, UnitRay ur, float wu, vec3 Lu, vec2 density)   one container's
//              fibers, blended (Lu: the key light in the container's frame; density: the self-shadow
//              estimate's fibers per unit path, 0 without, and the occlusion strength)
// The footprint is a tent across the fiber (the cone's cross-section seen perpendicular to the fiber's
// projection), half-width uFootprint * t: C1 in the ray's position, so a sub-pixel camera move changes a
// fiber's share by a sub-pixel amount instead of switching it on or off. Fibers are scanned ring by ring in
// ray order (front arcs outer to inner, back arcs inner to outer) and composited front to back until the
// footprint is opaque; their shading inputs (centre, normal, tint, roughness, depth) are averaged with the
// composite's weights and shaded once (stages/walk.frag): shading each fiber would cost a shading per
// covering fiber, several times the frame (docs/antialias.md says what was measured). Ids and depth stay
// the exact traversal's (traverse.glsl); this only colours. Straight fibers only (shaped fibers keep the
// nearest fiber's colour). Twin: app/reference.py: footprint_coverage (numpy); OSL has none: Cycles
// filters by its own sampling.

#include "common/epsilon.glsl"
#include "common/hash.glsl"
#include "geometry/container.glsl"
#include "fibers/layout.glsl"
#include "fibers/candidates.glsl"
#include "fibers/ray_path.glsl"
#include "fibers/counters.glsl"

#ifndef FIBERS_COVERAGE_GLSL
#define FIBERS_COVERAGE_GLSL

#ifndef COVER_CAP
#define COVER_CAP 48        // candidates per ring visit (renderer.py: COVER_CAP, its loop budget)
#endif
#ifndef COVER_SAMPLES
#define COVER_SAMPLES 6     // slots a footprint samples per ring before it thins them (see cover_straight)
#endif
#define COVER_WU_MAX 1.0    // footprint half-width, unit space: past a container's radius a fiber is a medium
#ifndef COVER_OPAQUE
#define COVER_OPAQUE 0.03   // transmittance at which the scan stops (see cover_straight: alpha)
#endif

uniform float uFootprint;   // footprint half-width per unit distance: quality.filter_width * the pixel angle
uniform int uCoverOn;       // 0: this draw adds no colour (the fiber ranges after the first, renderer.py)

// The tent's cumulative share up to v (in half-widths): 0 at -1, 1/2 at 0, 1 at 1, C1 in between.
float tent_cdf(float v) {
    v = clamp(v, -1.0, 1.0);
    return v <= 0.0 ? 0.5 * (1.0 + v) * (1.0 + v) : 1.0 - 0.5 * (1.0 - v) * (1.0 - v);
}

// The share of a tent footprint of half-width w, centred at distance x from a fiber's axis, that the
// fiber (a band of half-width r) covers; a step in x where w -> 0, r / w of the footprint where w >> r.
float footprint_coverage(float x, float r, float w) {
    float inv = 1.0 / max(w, 1e-30);
    return clamp(tent_cdf((r - x) * inv) - tent_cdf((-r - x) * inv), 0.0, 1.0);
}

// to_unit_space for the footprint: the bounding cylinder and the unit cylinder grown by the footprint, so
// rays that pass a container within a footprint of its fibers still see them. wu: the footprint's half-
// width in unit space at the container (one value per container: it changes across one by its width over
// the distance). On a miss [s0, s1] is empty, as to_unit_space leaves it.
bool to_unit_space_dilated(Segment seg, vec3 rd, float tNear, out UnitRay ur, out float wu) {
    mat3 localFromWorld = transpose(mat3(seg.ex, seg.ey, seg.ez));
    vec3 o = localFromWorld * (-seg.p0);
    vec3 d = localFromWorld * rd;
    float grow = uFootprint * (length(seg.p0) + seg.h + 2.0 * seg.rBound);     // the farthest point's footprint
    vec2 c = circle_interval(o.xy, d.xy, vec2(0.0), seg.rBound * (1.0 + EPS_BOUND) + grow);
    vec2 z = slab(o.z, d.z, seg.zLo, seg.zHi);
    float tb0 = max(max(c.x, z.x), tNear);
    float tb1 = min(c.y, z.y);
    bool bounded = tb0 <= tb1;
    ur.tb = bounded ? tb0 : tNear;
    ur.o = bounded ? o + tb0 * d : vec3(0.0);
    ur.d = d;
    ur.wO = seg.r0 + seg.kappa * ur.o.z;
    ur.O = ur.o / ur.wO;
    vec3 D = d * ur.wO - ur.o * (seg.kappa * d.z);
    ur.Dlen = length(D);
    ur.D = D / ur.Dlen;
    wu = min(uFootprint * (ur.tb + seg.rBound) / max(ur.wO, 1e-30), COVER_WU_MAX);
    vec2 cyl = circle_interval(ur.O.xy, ur.D.xy, vec2(0.0), 1.0 + wu);
    ur.s0 = max(cyl.x, 0.0);
    ur.s1 = cyl.y;
    clip_half_space(ur.O, ur.D, -seg.r0 * seg.n0, 0.0, ur.s0, ur.s1);
    clip_half_space(ur.O, ur.D, seg.r0 * seg.n1 + vec3(0.0, 0.0, seg.n1.z * seg.h * seg.kappa),
                    seg.n1.z * seg.h, ur.s0, ur.s1);
    bool inside = bounded && ur.s0 <= ur.s1;
    ur.s0 = inside ? ur.s0 : INF;
    ur.s1 = inside ? ur.s1 : -INF;
    return inside;
}

// What one container's fibers do to a footprint: alpha = 1 - their transmittance, and the weighted means
// (weights a_i T_i, front to back) of what shading needs: the centre, the offset from it to the covered
// part's surface (unit space), the ray parameter, the tint and roughness randoms.
struct CoverBlend {
    float alpha;
    vec2 c;
    vec2 radial;
    float s;
    float tint;
    float rough;
    float light;    // the key light's transmittance (density estimate), averaged per fiber
    float occlusion;
    int tests;
};

CoverBlend cover_straight(Segment seg, UnitRay ur, float wu, vec3 Lu, vec2 density) {
    CoverBlend b;
    RayPath rp = ray_path(ur);
    vec2 d2 = ur.D.xy;
    float a2 = dot(d2, d2);
    float invA = a2 > 0.0 ? 1.0 / a2 : 0.0;
    vec2 dn = rp.sa > 0.0 ? d2 / rp.sa : vec2(1.0, 0.0);
    vec2 n2 = vec2(-dn.y, dn.x);
    float sMid = path_s(rp, 0.0);                       // the closest approach: front visits before, back after
    float zScale = seg.h / (seg.v1 - seg.v0);
    float invW = 1.0 / max(wu, 1e-30);
    // a ray along the axis sees the fibers end on: no footprint across them; leave it to the exact colour
    bool any = ur.s0 <= ur.s1 && uFiberRadius > 0.0 && rp.sa > 0.0 && uCoverOn != 0;
    int K = uRings;
    float T = 1.0;
    vec2 sc = vec2(0.0), sr = vec2(0.0);
    float ss = 0.0, st = 0.0, sro = 0.0, sw = 0.0, sd = 0.0, sl = 0.0, so = 0.0;
    // light and occlusion fall off exponentially with depth: the mean of a blend's fibers is brighter than
    // a fiber at their mean depth, so each fiber's own are averaged (light: the path to the wall in the
    // container's cross-section, as fiber_shading.glsl: light_transmittance takes it; joints block none)
    vec2 l2 = Lu.xy;
    float ll = dot(l2, l2);
    float invL = ll > 0.0 ? 1.0 / ll : 0.0;
    int tests = 0;
    // the deepest ring the grown footprint can reach (one ring of slack for the rings' radial jitter): a
    // ray past a container's edge visits only its outer rings
    int deep = clamp(int((1.0 - rp.dist + wu + uFiberRadius) * float(K)) + 1, 0, K - 1);
    for (int p = 0; p < (any ? 2 * deep + 2 : 0); p++) {
        bool back = p > deep;
        int i = back ? 2 * deep + 1 - p : p;
        vec4 ring = uRingA[i];
        vec4 ringB = uRingB[i];
        float rf = uRingRadius[i];
        float rMin = max(ring.x - ringB.x, 0.0);            // the ring's fibre centres lie in [rMin, rMax]
        float rMax = ring.x + ringB.x;
        float rOut = rMax + rf + wu;
        float rIn = max(rMin - rf - wu, 0.0);
        float hOut = sqrt(max(0.0, (rOut - rp.dist) * (rOut + rp.dist)));
        float hIn = sqrt(max(0.0, (rIn - rp.dist) * (rIn + rp.dist)));
        bool reached = rp.dist < rOut;
        float psiA = back ? atan(hIn, rp.dist) : atan(-hOut, rp.dist);
        float psiB = back ? atan(hOut, rp.dist) : atan(-hIn, rp.dist);
        // the slots a fiber within the footprint can have: the arc's angles, the ring's reach, and the
        // angle the footprint and the fiber's radius subtend at the ring's innermost centre
        float grow = (rf + wu) < rMin ? asin((rf + wu) / rMin) : 3.14159265;
        float reach = ring.w + grow + EPS_ANGLE;
        int n = uRingN[i].x;
        int dir = int(rp.sigma);
        float first = (rp.thD + rp.sigma * (psiA - reach) - ring.z) * ringB.z;
        float last = (rp.thD + rp.sigma * (psiB + reach) - ring.z) * ringB.z;
        int j0 = dir > 0 ? int(ceil(first)) : int(floor(first));
        int j1 = dir > 0 ? int(floor(last)) : int(ceil(last));
        int want = min(max(0, (j1 - j0) * dir + 1), n);
        // Thinning: where the footprint holds more than COVER_SAMPLES of the ring's slots, every m-th slot
        // (m a power of two that divides n, from the footprint's width alone, so neighbouring pixels thin
        // alike) stands for m fibers: it covers 1 - (1 - a)^m. The slots kept are fixed on the ring (j a
        // multiple of m), so a fiber enters and leaves the footprint at its tent's edges as unthinned.
        float slots = 2.0 * grow * ringB.z + 1.0;
        int m = 1 << clamp(int(ceil(log2(slots / float(COVER_SAMPLES)))), 0, 6);
        m = min(m, n & -n);                             // n & -n: the largest power of two dividing n
        int u0 = dir > 0 ? m * int(ceil(float(j0) / float(m))) : m * int(floor(float(j0) / float(m)));
        int spread = (j1 - u0) * dir;
        int kept = spread >= 0 ? min(spread / m + 1, n / m) : 0;
        // past the cap, the middle of the window: the fibers nearest the footprint's centre line
        int count = reached ? min(kept, COVER_CAP) : 0;
        u0 += dir * m * ((kept - count) / 2);
        float mf = float(m);
        uint ringKey = ring_key(uSeed, seg.guide, i);
        for (int t = 0; t < count; t++) {
            gIters++;
            tests++;
            int u = u0 + dir * m * t;
            int j = u - n * int(floor(float(u) / float(n)));
            vec2 c;
            float vEnd;
            fiber_center_keyed(ring, ringB, ringKey, i, j, c, vEnd);
            vec2 oc = ur.O.xy - c;
            float s = -dot(oc, d2) * invA;                  // closest approach to the fiber's axis
            float x = dot(oc + s * d2, n2);                 // signed offset across it
            float z = ur.O.z + s * ur.D.z;
            float zl = (vEnd - seg.v0) * zScale;
            float zc = vEnd >= seg.v1 ? INF : zl / (seg.r0 + seg.kappa * zl);
            // the tip: the footprint slides off the fiber's cut end as it does off its side
            float tip = clamp(0.5 + 0.5 * (zc - z) * invW, 0.0, 1.0);
            bool mine = back ? s >= sMid : s < sMid;        // each fiber once: on the visit of its side
            bool valid = mine && s >= ur.s0 && s <= ur.s1 && vEnd > seg.v0;
            float a1 = valid ? footprint_coverage(abs(x), rf, wu) * tip : 0.0;
            float a = 1.0 - pow(max(1.0 - a1, 0.0), mf);
            float w = a * T;
            T *= 1.0 - a;
            // the covered part of the fiber's width, and its surface point facing the ray
            float lo = max(-rf, x - wu);
            float hi = min(rf, x + wu);
            float xc = 0.5 * (lo + hi);
            vec2 radial = xc * n2 - sqrt(max(rf * rf - xc * xc, 0.0)) * dn;
            uint key = fiber_key(uSeed, seg.guide, uint(i), uint(j));
            sw += w;
            vec2 q = c + radial;
            float qb = dot(q, l2);
            float path = ll > 0.0 ? (-qb + sqrt(max(qb * qb - ll * (dot(q, q) - 1.0), 0.0))) * invL : INF;
            sl += w * (density.x > 0.0 ? exp(-density.x * max(path, 0.0)) : 1.0);   // no 0 * INF
            so += w * mix(1.0, exp(-3.0 * (1.0 - length(c))), density.y);
            sc += w * c;
            sd += w * length(c);
            sr += w * radial;
            ss += w * s;
            st += w * (key_random(key, CH_TINT) - 0.5);
            sro += w * (key_random(key, CH_ROUGH) - 0.5);
        }
        if (T < COVER_OPAQUE) break;
    }
    float inv = sw > 0.0 ? 1.0 / sw : 0.0;
    // the scan stops once less than COVER_OPAQUE of the footprint shows through: alpha reaches 1 there and
    // runs on continuously from it (1 - T rescaled), so where the stop falls makes no step in the picture
    b.alpha = 1.0 - max(T - COVER_OPAQUE, 0.0) / (1.0 - COVER_OPAQUE);
    // the mean centre's direction at the mean depth in the container: the mean of centres on an arc lies
    // inside it, and occlusion and the self-shadow estimate would darken a footprint the fibers do not
    float lc = length(sc);
    b.c = lc > 0.0 ? sc * (sd * inv / lc) : vec2(0.0);
    b.radial = sr * inv;
    b.s = ss * inv;
    b.tint = st * inv;
    b.rough = sro * inv;
    b.light = sw > 0.0 ? sl * inv : 1.0;
    b.occlusion = sw > 0.0 ? so * inv : 1.0;
    b.tests = tests;
    return b;
}

#endif
