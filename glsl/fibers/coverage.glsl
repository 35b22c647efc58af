// coverage.glsl: the filtered mode (quality.filter = coverage, FILTER 1): a pixel's ray is a cone, and
// every fiber of a container contributes the share of the cone's footprint it covers.
//   float footprint_coverage(float x, float r, float w)   share of a tent footprint a fiber covers
//   bool  to_unit_space_dilated(Segment seg, vec3 rd, float tNear, out UnitRay ur, out float wu)
//   Fence ring_fence(rho, n, rf); float ring_fence_cover(Fence f, float d, float w)   a ring as a medium
//   float medium_weight(float wu, float fibers, float rings)   0: scan the fibers .. 1: a medium
//   CoverBlend cover_container(Segment seg, UnitRay ur, float wu, vec3 Lu, vec2 density)   one container's
//              fibers, blended (Lu: the key light in the container's frame; density: the self-shadow
//              estimate's fibers per unit path, 0 without, and the occlusion strength)
// The footprint is a tent across the fiber (the cone's cross-section seen perpendicular to the fiber's
// projection), half-width uFootprint * t: C1 in the ray's position, so a sub-pixel camera move changes a
// fiber's share by a sub-pixel amount instead of switching it on or off. Where the footprint holds few of
// a container's fibers they are scanned ring by ring in ray order (front arcs outer to inner, back arcs
// inner to outer) and composited front to back until the footprint is opaque (cover_scan); where it holds
// many, the container is a medium: each ring's expected share of the footprint, in closed form
// (cover_medium), so its cost no longer grows with the fibers a footprint holds; in between the two are
// blended by the fibers a footprint spans per ring (medium_weight), so a dolly sees no step. Either way
// the shading inputs (centre, normal, tint, roughness, depth, light, occlusion) are averaged with the
// composite's weights and shaded once (stages/walk.frag): shading each fiber would cost a shading per
// covering fiber, several times the frame (docs/antialias.md says what was measured). Ids and depth stay
// the exact traversal's (traverse.glsl); this only colours. Curved fibers (SHAPED) are taken at the height
// where the ray crosses each ring (arc_shape), their curl and frizz as a wider footprint. Twins: app/reference.py (footprint_coverage, the fence,
// medium_weight, exp_mean, medium_alpha); OSL has none: Cycles filters by its own sampling.

#include "common/epsilon.glsl"
#include "common/hash.glsl"
#include "geometry/container.glsl"
#include "fibers/layout.glsl"
#include "fibers/candidates.glsl"
#include "fibers/ray_path.glsl"
#include "fibers/counters.glsl"
#include "fibers/shape.glsl"
#include "fibers/taper.glsl"
#include "shading/tangent.glsl"

#ifndef FIBERS_COVERAGE_GLSL
#define FIBERS_COVERAGE_GLSL

#ifndef SHAPED
#define SHAPED 0
#endif

#ifndef COVER_CAP
#define COVER_CAP 48        // candidates per ring visit (renderer.py: COVER_CAP, its loop budget)
#endif
// The slots a footprint samples per ring before the scan thins them (see cover_scan): COVER_SAMPLES, but
// at most COVER_CONTAINER_SAMPLES over the container's rings, and never fewer than COVER_SAMPLES_MIN. A ray
// composites a sample from each ring it crosses, twice, so a thinned ring's error is averaged with the
// others': groom_auto's 7-ring sintel containers (3 a ring) cost 15% less for 0.3 levels of error; the
// 3-ring fur-ball keeps 6.
#ifndef COVER_SAMPLES
#define COVER_SAMPLES 6
#endif
#ifndef COVER_CONTAINER_SAMPLES
#define COVER_CONTAINER_SAMPLES 18.0
#endif
#ifndef COVER_BUDGET_THIN
#define COVER_BUDGET_THIN 4
#endif
#ifndef COVER_SAMPLES_MIN
#define COVER_SAMPLES_MIN 3.0
#endif
#define COVER_WU_MAX 1.0    // footprint half-width, unit space: past a container's radius a fiber is a medium
#ifndef COVER_OPAQUE
#define COVER_OPAQUE 0.06   // transmittance at which the scan stops (see cover_container: alpha; 0.03 cost
                            // sintel 4% more for 0.3 levels less error, docs/antialias.md)
#endif
// Where a container becomes a medium (medium_weight): the fiber slots of a mean ring the footprint spans
// at which the medium starts to blend in, and at which it has replaced the scan. The scan thins past
// COVER_SAMPLES slots a ring visit; from twice that its cost grows with the slots while the medium's is
// fixed per ring, and both agree on the error there (docs/antialias.md).
#ifndef COVER_MEDIUM_FROM
#define COVER_MEDIUM_FROM 12.0
#endif
#ifndef COVER_MEDIUM_FULL
#define COVER_MEDIUM_FULL 20.0
#endif
#ifndef COVER_LIGHT_NODES
#define COVER_LIGHT_NODES 5  // cover_medium: points across an arc at which the medium takes the key light's path
#endif
#define COVER_TENT_MIN 0.01  // ring_fence_cover: footprint half-width, in ring radii, below which it is a line

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
    wu = uFootprint * (ur.tb + seg.rBound) / max(ur.wO, 1e-30);
    vec2 cyl = circle_interval(ur.O.xy, ur.D.xy, vec2(0.0), 1.0 + wu);
    ur.s0 = max(cyl.x, 0.0);
    ur.s1 = cyl.y;
    clip_half_space(ur.O, ur.D, -seg.r0 * seg.n0, 0.0, ur.s0, ur.s1);
    clip_half_space(ur.O, ur.D, seg.r0 * seg.n1 + vec3(0.0, 0.0, seg.n1.z * seg.h * seg.kappa),
                    seg.n1.z * seg.h, ur.s0, ur.s1);
    bool inside = bounded && ur.s0 <= ur.s1;
    ur.s0 = inside ? ur.s0 : INF;
    ur.s1 = inside ? ur.s1 : -INF;
    ur.sKnown = INF;
    return inside;
}

// --- the medium: a container whose fibers are far below the footprint ----------------------------------
// A ring seen across: its fibers sit at a regular angular step (jitter is a small share of it), so they lie
// side by side like a fence, not scattered; where the ring runs along the footprint (near its tangent)
// neighbours overlap and the fence is closed. Per arc, the share of the cross axis its fibers cover at
// offset u is g(u) = min(1, kappa / sqrt(rho^2 - u^2)), kappa = n rf / pi (fibers per unit u times their
// width), 0 past the ring; closed (g = 1) for |u| >= ys = sqrt(rho^2 - kappa^2).
struct Fence {
    float rho;
    float kappa;
    float ys;
    float g1s;      // the antiderivative of g at ys ...
    float g2s;      // ... and the second one (ring_fence_f2's)
};

Fence ring_fence(float rho, float n, float rf) {
    Fence f;
    f.rho = rho;
    f.kappa = n * rf / 3.14159265;
    f.ys = sqrt(max(rho * rho - f.kappa * f.kappa, 0.0));
    float as = asin(min(f.ys / max(rho, EPS_DIVISOR), 1.0));
    f.g1s = f.kappa * as;
    f.g2s = f.kappa * (f.ys * as - f.ys * f.ys / (sqrt(max(rho * rho - f.ys * f.ys, 0.0)) + rho));
    return f;
}

// The second antiderivative of g, even in u, 0 at u = 0: kappa (u asin(u / rho) + sqrt(rho^2 - u^2) - rho)
// on the open part, the root's difference written without cancelling (the tent's second difference of
// this loses float32 digits to the function's size, so it is kept small).
float ring_fence_f2(Fence f, float u) {
    float a = abs(u);
    float open = f.kappa * (a * asin(min(a / max(f.rho, EPS_DIVISOR), 1.0))
                            - a * a / (sqrt(max(f.rho * f.rho - a * a, 0.0)) + f.rho));
    float closed = f.g2s + (f.g1s + 0.5 * (min(a, f.rho) - f.ys)) * (min(a, f.rho) - f.ys);
    float past = (f.g1s + f.rho - f.ys) * max(a - f.rho, 0.0);
    return a <= f.ys ? open : closed + past;
}

// The share of a tent footprint (half-width w, centre line d from the axis) one arc of the ring covers: the
// tent's second difference of ring_fence_f2. Below COVER_TENT_MIN of the radius the difference loses
// float32 digits, and the tent is a line anyway: g itself.
float ring_fence_cover(Fence f, float d, float w) {
    float tent = (ring_fence_f2(f, d + w) - 2.0 * ring_fence_f2(f, d) + ring_fence_f2(f, d - w))
               / max(w * w, EPS_DIVISOR);
    float line = abs(d) < f.rho ? min(1.0, f.kappa / sqrt(max(f.rho * f.rho - d * d, EPS_DIVISOR))) : 0.0;
    return clamp(w > COVER_TENT_MIN * f.rho ? tent : line, 0.0, 1.0);
}

// The fence's mean share over the ring's whole width (|u| < rho): how much of what lies inside the ring's
// silhouette it hides (1: a closed fence, as every bundled layout's rings nearly are).
float ring_fence_mean(Fence f) {
    return clamp((f.g1s + f.rho - f.ys) / max(f.rho, EPS_DIVISOR), 0.0, 1.0);
}

// How far a container is a medium: 0 (scan its fibers) to 1 (a medium), by the fiber slots the footprint
// (half-width wu) spans on a mean ring: fibers / rings slots around the ring halfway out (radius 1/2),
// smooth in between, so the camera's distance blends the one into the other without a step.
float medium_weight(float wu, float fibers, float rings) {
    return smoothstep(COVER_MEDIUM_FROM, COVER_MEDIUM_FULL, 2.0 * wu * fibers / (3.14159265 * max(rings, 1.0)));
}

// Where a footprint's rays first meet a ring's fibers, for the medium's light and occlusion (cover_medium).
// Where fibers do not overlap (k = n rf / (pi rho) fiber widths over each point of the ring, k <= 1) a ray
// meets one fiber, on its side facing the ray, its centre on the ring (rho). Where many overlap it meets
// the outermost of them on its outer side: that one's centre is out by the largest of k radial jitters
// uniform in +-dr, dr (k - 1) / (k + 1). In between, both by q = (k - 1) / (k + 1). Returns (the first
// fibers' centre radius, the radius of the circle the light is taken on, the share 1 - q of the facing
// side's offset kept). groom_auto's harolongo lays 6.8 fibers of 0.2 radii over each point of its outer
// ring (q = 0.75) under a self-shadow density of 8 a radius: taken at the ring's radius the medium was 19
// levels too dark (docs/antialias.md). The default preset's rings: k 1.2 .. 23, the outer one (all a
// footprint sees) 1.2. Twin: app.reference.medium_face.
vec3 medium_face(float rho, float n, float rf, float dr) {
    float k = n * rf / (3.14159265 * max(rho, EPS_DIVISOR));
    float q = max(k - 1.0, 0.0) / (k + 1.0);
    float centre = rho + q * q * dr;
    return vec3(centre, centre + q * rf, 1.0 - q);
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

// Weighted sums of a composite, front to back: T the transmittance so far, w the sum of weights (1 - T);
// the rest are sums of weight times the fiber's value.
struct CoverSums {
    float T;
    float w;
    vec2 c;
    float d;        // |c|: the centres' mean depth in the container
    vec2 radial;
    float s;
    float tint;
    float rough;
    float light;
    float occlusion;
};

CoverSums cover_sums_empty() {
    return CoverSums(1.0, 0.0, vec2(0.0), 0.0, vec2(0.0), 0.0, 0.0, 0.0, 0.0, 0.0);
}

// one more of weight w (a share of the footprint) into u, whatever lies in front of it
void cover_weigh(inout CoverSums u, float w, vec2 c, vec2 radial, float s, float light, float occlusion) {
    u.w += w;
    u.c += w * c;
    u.d += w * length(c);
    u.radial += w * radial;
    u.s += w * s;
    u.light += w * light;
    u.occlusion += w * occlusion;
}

// one more fiber (or stretch of medium) of coverage a, behind all that is in u
void cover_under(inout CoverSums u, float a, vec2 c, vec2 radial, float s, float tint, float rough,
                 float light, float occlusion) {
    float w = a * u.T;
    u.T *= 1.0 - a;
    cover_weigh(u, w, c, radial, s, light, occlusion);
    u.tint += w * tint;
    u.rough += w * rough;
}

// every weight of u times k
CoverSums cover_scaled(CoverSums u, float k) {
    return CoverSums(u.T, k * u.w, k * u.c, k * u.d, k * u.radial, k * u.s, k * u.tint, k * u.rough,
                     k * u.light, k * u.occlusion);
}

// front, then back behind it
CoverSums cover_then(CoverSums f, CoverSums b) {
    float T = f.T;
    return CoverSums(f.T * b.T, f.w + T * b.w, f.c + T * b.c, f.d + T * b.d, f.radial + T * b.radial,
                     f.s + T * b.s, f.tint + T * b.tint, f.rough + T * b.rough, f.light + T * b.light,
                     f.occlusion + T * b.occlusion);
}

// (1 - k) a + k b, field by field: the blend of scan and medium
CoverSums cover_mix(CoverSums a, CoverSums b, float k) {
    return CoverSums(mix(a.T, b.T, k), mix(a.w, b.w, k), mix(a.c, b.c, k), mix(a.d, b.d, k),
                     mix(a.radial, b.radial, k), mix(a.s, b.s, k), mix(a.tint, b.tint, k),
                     mix(a.rough, b.rough, k), mix(a.light, b.light, k), mix(a.occlusion, b.occlusion, k));
}

// The distance from q to the container's wall along the key light (l2: its direction's xy in the
// container's frame, ll = |l2|^2, the path a unit-length light direction runs in 3D), INF where it runs
// along the axis.
float cover_light_path(vec2 q, vec2 l2, float ll) {
    float invL = ll > 0.0 ? 1.0 / ll : 0.0;
    float qb = dot(q, l2);
    return ll > 0.0 ? (-qb + sqrt(max(qb * qb - ll * (dot(q, q) - 1.0), 0.0))) * invL : INF;
}

// The mean of exp(-k p) for p running linearly from p0 to p1, given e0 = exp(-k p0) and e1 = exp(-k p1)
// (k = 0: 1 whatever the paths; a path of INF: no light).
float exp_mean(float k, float p0, float p1, float e0, float e1) {
    float spread = k * abs(p1 - p0);
    return spread > 1e-3 && p0 < INF && p1 < INF ? abs(e0 - e1) / spread : 0.5 * (e0 + e1);
}

// The key light's transmittance at q, a fiber's point in the container's cross-section (density estimate:
// the path to the wall of the blended guide's cylinder in the frame lf, as fiber_shading.glsl:
// light_transmittance takes it, so the shadow runs on across joints; the root and tip are left out), and
// the occlusion of a fiber at depth |c|: each fiber's own, since both fall off exponentially with depth and
// the mean of a blend's fibers is brighter than a fiber at their mean depth.
vec2 cover_light(LightFrame lf, vec2 q, vec2 c, vec2 density) {
    float path = joint_light_path_unit(lf, q);
    return vec2(density.x > 0.0 ? exp(-density.x * max(path, 0.0)) : 1.0,      // no 0 * INF
                mix(1.0, exp(-3.0 * (1.0 - length(c))), density.y));
}

// Curved fibers (SHAPED: ellipsoid, twist, curl, frizz): the shape of ring i where the ray crosses the
// ring's radius rho on one side of its closest approach (the arc's height v): the ellipsoid's scale and the
// twist there. The scan and the medium take each fiber as the vertical line through its scaled, turned rest
// position at that height: exact where the ray crosses the container square to its axis (one height), off
// by the rest line's turn over the ray's rise across the footprint otherwise. The curl and frizz sway a
// fiber about that line (cover_container widens the footprint by their spread instead of following them).
struct ArcShape {
    float v;
    float e;        // ellipsoid: every ring's radius times e
    float tau;      // twist: the ring's pattern turned by tau about the axis
};

ArcShape arc_shape(Segment seg, UnitRay ur, RayPath rp, float rho, bool back, int ring) {
    ArcShape a;
#if SHAPED
    float h = sqrt(max(rho * rho - rp.dist * rp.dist, 0.0));
    float s = rp.sa > 0.0 ? ((back ? h : -h) - rp.x0) / rp.sa : 0.0;
    a.v = unit_to_v(seg, ur.O.z + clamp(s, ur.s0, ur.s1) * ur.D.z);
    a.e = shape_scale(a.v);
    a.tau = shape_twist(a.v, ring);
#else
    a.v = 0.0;
    a.e = 1.0;
    a.tau = 0.0;
#endif
    return a;
}

// floor(a / b) for b > 0, in float (llvmpipe divides integers lane by lane; exact for |a| < 2^24)
int floor_div(int a, int b) {
    return int(floor(float(a) / float(b)));
}

// The kept slots of a thinned ring (every m-th of its n, keptRing of them) at or below slot x, x counted on
// past the ring's end or before its start (so negative below slot 0): where a window's first and last are.
int cover_kept_upto(int x, int n, int m, int keptRing) {
    int q = floor_div(x, n);
    return q * keptRing + min(floor_div(x - q * n, m) + 1, keptRing);
}

// The tip taper's mean width at guide height v (taper.glsl: 1 up to uTaperStart of a fiber's own length,
// then down to uTipWidth at its end), taken for the fiber ending halfway along what is left of the ends'
// spread past v (length jitter: the ends are uniform over the last uLengthJitter of the guide): the
// medium's fibers, where the scan takes each fiber's own.
float taper_mean_width(float v) {
    float vEnd = 0.5 * (max(v, 1.0 - uLengthJitter) + 1.0);
    float vStart = uTaperStart * vEnd;
    float along = clamp((v - vStart) / max(vEnd - vStart, EPS_DIVISOR), 0.0, 1.0);
    return mix(1.0, uTipWidth, along);
}

// The scan: the fibers themselves, ring by ring in ray order (see cover_container).
CoverSums cover_scan(Segment seg, UnitRay ur, RayPath rp, float wu, vec3 Lu, vec2 density, bool on,
                     inout int tests) {
    CoverSums u = cover_sums_empty();
    vec2 d2 = ur.D.xy;
    float a2 = dot(d2, d2);
    float invA = a2 > 0.0 ? 1.0 / a2 : 0.0;
    vec2 dn = rp.sa > 0.0 ? d2 / rp.sa : vec2(1.0, 0.0);
    vec2 n2 = vec2(-dn.y, dn.x);
    float sMid = path_s(rp, 0.0);                       // the closest approach: front visits before, back after
    float zScale = seg.h / (seg.v1 - seg.v0);
    float invW = 1.0 / max(wu, 1e-30);
    // the key light's frame for the fibers' self-shadow (cover_light), taken once where the ray comes
    // nearest the axis inside the container: it turns slowly along a segment, and a footprint's fibers lie
    // close to the ray
    vec3 near = ur.O + clamp(sMid, ur.s0, ur.s1) * ur.D;
    LightFrame lf = joint_light_frame(seg.n0, seg.n1, vec3(0.0, 0.0, seg.h),
                                      near * (seg.r0 / (1.0 - seg.kappa * near.z)), Lu);
#if TAPER
    TaperSeg ts = taper_seg(seg.v0, seg.v1, zScale, seg.r0, seg.kappa);
#endif
    int K = uRings;
    float samples = clamp(COVER_CONTAINER_SAMPLES / float(K), COVER_SAMPLES_MIN, float(COVER_SAMPLES));
    // the deepest ring the grown footprint can reach (one ring of slack for the rings' radial jitter): a
    // ray past a container's edge visits only its outer rings
    int deep = clamp(int((1.0 - rp.dist + wu + uFiberRadius) * float(K)) + 1, 0, K - 1);
    for (int p = 0; p < (on ? 2 * deep + 2 : 0); p++) {
        bool back = p > deep;
        int i = back ? 2 * deep + 1 - p : p;
        vec4 ring = uRingA[i];
        vec4 ringB = uRingB[i];
        float rf = uRingRadius[i];
        ArcShape sh = arc_shape(seg, ur, rp, ring.x, back, i);
        // the ring's fibre centres lie in [rMin, rMax]
        float rMin = max(sh.e * (ring.x - ringB.x), 0.0);
        float rMax = sh.e * (ring.x + ringB.x);
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
        // A visit counts only the fibers on its side of the closest approach (mine, below): the front half
        // of the ring (psi in [-pi, 0]) or the back half ([0, pi]), give or take a fiber's angular offset
        // from its slot. Where the footprint reaches past a ring's inner side (grow = pi) the window would
        // be the whole ring on both visits, every fiber tested twice to count it once.
        float halfLo = (back ? 0.0 : -3.14159265) - ring.w - EPS_ANGLE;
        float halfHi = (back ? 3.14159265 : 0.0) + ring.w + EPS_ANGLE;
        // (the slots' angles are the ring's own: the twist turns the ray the other way)
        float first = (rp.thD - sh.tau + rp.sigma * max(psiA - reach, halfLo) - ring.z) * ringB.z;
        float last = (rp.thD - sh.tau + rp.sigma * min(psiB + reach, halfHi) - ring.z) * ringB.z;
        int j0 = dir > 0 ? int(ceil(first)) : int(floor(first));
        int j1 = dir > 0 ? int(floor(last)) : int(ceil(last));
        // Thinning: where the footprint holds more than `samples` of the ring's slots, every m-th slot
        // (m a power of two, from the footprint's width alone, so neighbouring pixels thin alike) stands for
        // the m fibers from it on: it covers 1 - (1 - a)^m. The slots kept are fixed on the ring (j a multiple
        // of m, 0 <= j < n), so a fiber enters and leaves the footprint at its tent's edges as unthinned;
        // where m does not divide n the last one stands for the n mod m left (groom_auto's even spacing
        // gives rings of any count; when m had to divide n, sintel's 19, 26, 30, 30, 24, 14, 5 fibers were
        // thinned by 2 at most).
        float slots = 2.0 * grow * ringB.z + 1.0;
        // (the rings' budget thins a kept slot to at most COVER_BUDGET_THIN fibers past what COVER_SAMPLES
        // asks: where the footprint spans many fibers a ring, the default preset's 360, twice the lumps
        // showed against the fibers themselves, tests/render/test_explicit_filter.py)
        int m = max(1 << clamp(int(ceil(log2(slots / float(COVER_SAMPLES)))), 0, 6),
                    min(1 << clamp(int(ceil(log2(slots / samples))), 0, 6), COVER_BUDGET_THIN));
        m = min(m, max(n, 1));
        int keptRing = (n + m - 1) / m;                 // the kept slots around the ring: 0, m, .., n - 1
        // the window [lo, hi] in slots counted on past the ring's end (or before its start), and the
        // kept slots in it, as indices g into the kept slots counted on alike
        bool nonEmpty = (j1 - j0) * dir >= 0;
        int lo = dir > 0 ? j0 : j1;
        int hi = dir > 0 ? j1 : j0;
        int gLo = cover_kept_upto(lo - 1, n, m, keptRing);
        int gHi = cover_kept_upto(hi, n, m, keptRing) - 1;
        int kept = nonEmpty ? min(gHi + 1 - gLo, keptRing) : 0;
        // past the cap, the middle of the window: the fibers nearest the footprint's centre line
        int count = reached ? min(kept, COVER_CAP) : 0;
        int g0 = dir > 0 ? gLo + (kept - count) / 2 : gHi - (kept - count) / 2;
        uint ringKey = ring_key(uSeed, seg.guide, i);
        for (int t = 0; t < count; t++) {
            gIters++;
            tests++;
            int g = g0 + dir * t;
            int j = m * (g - keptRing * floor_div(g, keptRing));
            float mf = float(min(m, n - j));
            vec2 c;
            float vEnd;
            fiber_center_keyed(ring, ringB, ringKey, i, j, c, vEnd);
#if SHAPED
            c = sh.e * vec2(cos(sh.tau) * c.x - sin(sh.tau) * c.y, sin(sh.tau) * c.x + cos(sh.tau) * c.y);
#endif
            vec2 oc = ur.O.xy - c;
            float s = -dot(oc, d2) * invA;                  // closest approach to the fiber's axis
            float x = dot(oc + s * d2, n2);                 // signed offset across it
            float z = ur.O.z + s * ur.D.z;
            float zl = (vEnd - seg.v0) * zScale;
            float zc = vEnd >= seg.v1 ? INF : zl / (seg.r0 + seg.kappa * zl);
            // the tip: the footprint slides off the fiber's cut end as it does off its side
            float tip = clamp(0.5 + 0.5 * (zc - z) * invW, 0.0, 1.0);
#if TAPER
            // the fiber's width where the ray passes it: its tip taper's line at that height (taper.glsl)
            vec2 line = taper_line(ts, vEnd);
            float rw = rf * clamp(line.x + line.y * z, 0.0, 1.0);
#else
            float rw = rf;
#endif
            bool mine = back ? s >= sMid : s < sMid;        // each fiber once: on the visit of its side
            bool valid = mine && s >= ur.s0 && s <= ur.s1 && vEnd > seg.v0;
            float a1 = valid ? footprint_coverage(abs(x), rw, wu) * tip : 0.0;
            float a = 1.0 - pow(max(1.0 - a1, 0.0), mf);
            // the covered part of the fiber's width, and its surface point facing the ray
            float lo = max(-rw, x - wu);
            float hi = min(rw, x + wu);
            float xc = 0.5 * (lo + hi);
            vec2 radial = xc * n2 - sqrt(max(rw * rw - xc * xc, 0.0)) * dn;
            uint key = fiber_key(uSeed, seg.guide, uint(i), uint(j));
            vec2 lo2 = cover_light(lf, c + radial, c, density);
            cover_under(u, a, c, radial, s, key_random(key, CH_TINT) - 0.5, key_random(key, CH_ROUGH) - 0.5,
                        lo2.x, lo2.y);
        }
        if (u.T < COVER_OPAQUE) break;
    }
    return u;
}

// The medium: per ring, the share of the footprint each of its two arcs covers (ring_fence_cover), placed
// where the footprint's centre line crosses the ring (or passes nearest to it). The rings are nested: an
// inner ring lies inside the silhouette of every outer one, so what the outer front arcs let through of it
// is their fences' open share (1 - ring_fence_mean), not what they let through of the whole footprint
// (which, for a footprint wider than the container, would show the inner rings through the outer ones'
// margins). Front arcs outer to inner, then back arcs inner to outer, each under the front arcs of its own
// ring and the rings outside it and under the back arcs inside it (the inner rings' front arcs hide only
// the part of an outer back arc within their silhouette; counting them whole measured worse). An arc counts the share of its stretch of
// path inside the container's window [s0, s1] (joints and caps: the neighbour counts the rest) and the share
// of its fibers that reach so far along the guide (length jitter: their ends are uniform over the last
// uLengthJitter of it). Tint and roughness randoms average to 0 over many fibers.
CoverSums cover_medium(Segment seg, UnitRay ur, RayPath rp, float wu, vec2 l2, vec2 density, bool on,
                       inout int tests) {
    CoverSums front = cover_sums_empty();
    CoverSums back = cover_sums_empty();
    vec2 dn = rp.sa > 0.0 ? ur.D.xy / rp.sa : vec2(1.0, 0.0);
    vec2 out2 = -rp.sigma * vec2(-dn.y, dn.x);          // from the axis towards the path's closest point
    float invSa = rp.sa > 0.0 ? 1.0 / rp.sa : 0.0;
    float xs0 = rp.x0 + ur.s0 * rp.sa;                  // the window, as path positions
    float xs1 = rp.x0 + ur.s1 * rp.sa;
    float ll = dot(l2, l2);
    float d = rp.dist;
    float open = 1.0;                                   // what the front arcs so far let through
    // curved fibers: the rings scaled by the ellipsoid where the ray passes closest to the axis; the twist
    // turns a ring into itself
    ArcShape sh = arc_shape(seg, ur, rp, 0.0, false, 0);
#if TAPER
    // the tip taper thins the fibers where the ray passes: the medium takes their mean width there
    float thin = taper_mean_width(unit_to_v(seg, ur.O.z + clamp(path_s(rp, 0.0), ur.s0, ur.s1) * ur.D.z));
#else
    float thin = 1.0;
#endif
    int K = uRings;
    for (int i = 0; i < (on ? K : 0); i++) {
        tests++;
        float rf = uRingRadius[i] * thin;
        float rho = sh.e * uRingA[i].x;
        // the fence's edge is its fibers' outer side (their centres' jitter spreads it both ways); where
        // the fibers are, and what light reaches them, is their centres' radius
        Fence f = ring_fence(rho + rf, float(uRingN[i].x), rf);
        float fence = ring_fence_cover(f, d, wu);
        float hides = ring_fence_mean(f);
        // the arc's stretch of path: where the ring's fibers within the footprint have their closest
        // approach (the band |u| in [uLo, uHi] of the ring, seen along the path)
        float uLo = min(max(d - wu, 0.0), rho);
        float uHi = min(d + wu, rho);
        float xFar = sqrt(max(rho * rho - uLo * uLo, 0.0));
        float xNear = sqrt(max(rho * rho - uHi * uHi, 0.0));
        float y0 = min(d, rho);
        float xArc = sqrt(max(rho * rho - y0 * y0, 0.0));
        vec2 radial = -rf * dn;                         // the fibers' sides facing the ray, on average
        // The light falls off exponentially across an arc, so its value where the centre line meets the
        // ring is not the arc's mean: the path to the wall is taken piecewise linear in the angle around the
        // ring's face (medium_face: where rays first meet its fibers, mirrored about rho for the back arc)
        // between COVER_LIGHT_NODES points spread over the footprint's share of the arc (+-w / sqrt 2
        // about the centre line, a uniform spread of the tent's variance), each piece's exp averaged exactly
        // and weighted by its width across the footprint. x: front arc, y: back arc.
        vec3 seen = medium_face(rho, float(uRingN[i].x), rf, sh.e * uRingB[i].x);
        float face = seen.y;
        // the occlusion of the first fibers met: the outermost centres of the front arc, the innermost of the back
        vec2 occlusion = mix(vec2(1.0), exp(-3.0 * (1.0 - vec2(seen.x, 2.0 * rho - seen.x))), density.y);
        vec2 rad2 = seen.z * radial;
        float backFace = max(2.0 * rho - face, 0.0) / face;   // the back arc's: its mirror about rho
        float phiA = asin(clamp((d - 0.70710678 * wu) / face, -1.0, 1.0));
        float phiB = asin(clamp((d + 0.70710678 * wu) / face, -1.0, 1.0));
        vec2 light = vec2(0.0);
        vec2 pathPrev = vec2(0.0);
        vec2 ePrev = vec2(0.0);
        float yPrev = 0.0;
        for (int k = 0; k < COVER_LIGHT_NODES; k++) {
            float phi = mix(phiA, phiB, float(k) / float(COVER_LIGHT_NODES - 1));
            float y = face * sin(phi);
            vec2 cy = y * out2 + rad2;
            vec2 cx = face * cos(phi) * dn;
            vec2 path = max(vec2(cover_light_path(cy - cx, l2, ll),
                                 cover_light_path(y * out2 * backFace + rad2 + cx * backFace, l2, ll)), 0.0);
            vec2 e = density.x > 0.0 ? exp(-density.x * min(path, vec2(1e6))) : vec2(1.0);
            float wk = k > 0 ? y - yPrev : 0.0;
            light += k > 0 ? wk * vec2(exp_mean(density.x, pathPrev.x, path.x, ePrev.x, e.x),
                                       exp_mean(density.x, pathPrev.y, path.y, ePrev.y, e.y)) : vec2(0.0);
            pathPrev = path;
            ePrev = e;
            yPrev = y;
        }
        // (a footprint that meets the ring only at its edge: the light there)
        float spread = face * (sin(phiB) - sin(phiA));
        light = spread > 0.0 ? light / spread : ePrev;
        for (int side = 0; side < 2; side++) {
            float sg = side == 0 ? -1.0 : 1.0;
            float lo = side == 0 ? -xFar : xNear;
            float hi = side == 0 ? -xNear : xFar;
            float present = hi - lo > 1e-6 ? clamp((min(hi, xs1) - max(lo, xs0)) / (hi - lo), 0.0, 1.0)
                                           : float(lo >= xs0 && lo <= xs1);
            vec2 c = y0 * out2 + sg * xArc * dn;
            float s = (sg * xArc - rp.x0) * invSa;
            float v = unit_to_v(seg, ur.O.z + s * ur.D.z);
            present *= uLengthJitter > 0.0 ? clamp((1.0 - v) / uLengthJitter, 0.0, 1.0) : float(v < 1.0);
            if (side == 0) {
                cover_weigh(front, fence * present * open, c, radial, s, light.x, occlusion.x);
                open *= 1.0 - hides * present;
            } else {
                back = cover_scaled(back, 1.0 - hides * present);      // this back arc is nearer than those
                cover_weigh(back, fence * present * open, c, radial, s, light.y, occlusion.y);
            }
        }
        // the rings inside a closed fence add nothing (every lane of a batch past it: the loop ends)
        if (open < 1e-4) break;
    }
    CoverSums u = cover_then(front, back);              // front.T is 1: the weights are shares already
    // the shares can only add up past 1 where the fences' means undersell their coverage: then scaled to 1
    u = cover_scaled(u, 1.0 / max(u.w, 1.0));
    u.T = 1.0 - u.w;
    return u;
}

// A container's coverage: the scan where the footprint holds few fibers, the medium where it holds many,
// both blended in between (medium_weight). The scan visits the rings in ray order (front arcs outer to
// inner, back arcs inner to outer), each ring's candidate window grown by the footprint, and composites
// the fibers front to back until the footprint is opaque; a fiber is counted on the visit of its side of
// the ray's closest approach to the axis, so once. wu: the footprint's half-width in unit space (the scan
// takes at most COVER_WU_MAX of it: past a container's radius it is a medium).
CoverBlend cover_container(Segment seg, UnitRay ur, float wu, vec3 Lu, vec2 density) {
    CoverBlend b;
    RayPath rp = ray_path(ur);
    // a ray along the axis sees the fibers end on: no footprint across them; leave it to the exact colour
    bool any = ur.s0 <= ur.s1 && uFiberRadius > 0.0 && rp.sa > 0.0 && uCoverOn != 0;
    ivec2 last = uRingN[uRings - 1];
    float medium = medium_weight(wu, float(last.x + last.y), float(uRings));
#if SHAPED
    // the curl and frizz sway each fiber about its rest line, across the footprint by up to the
    // displacement: a helix's sway spreads as A^2 / 2, the tent's as w^2 / 6, and the footprint seen by a
    // swaying fiber is taken as the tent of their summed spread (the fiber's mean over its sway, so a ray
    // that meets a fiber at another height of its turn sees the same share)
    float disp = shape_displacement();
    wu = sqrt(wu * wu + 3.0 * disp * disp);
#endif
    int tests = 0;
    CoverSums scan = cover_scan(seg, ur, rp, min(wu, COVER_WU_MAX), Lu, density, any && medium < 1.0, tests);
    CoverSums med = cover_medium(seg, ur, rp, wu, Lu.xy, density, any && medium > 0.0, tests);
    // the scan stops once less than COVER_OPAQUE of the footprint shows through: alpha reaches 1 there and
    // runs on continuously from it (1 - T rescaled), so where the stop falls makes no step in the picture;
    // the medium's alpha is rescaled alike, so the two agree where they blend
    vec2 alphas = 1.0 - max(vec2(scan.T, med.T) - COVER_OPAQUE, 0.0) / (1.0 - COVER_OPAQUE);
    b.alpha = mix(alphas.x, alphas.y, medium);
    CoverSums u = cover_mix(scan, med, medium);
    float inv = u.w > 0.0 ? 1.0 / u.w : 0.0;
    // the mean centre's direction at the mean depth in the container: the mean of centres on an arc lies
    // inside it, and occlusion and the self-shadow estimate would darken a footprint the fibers do not
    float lc = length(u.c);
    b.c = lc > 0.0 ? u.c * (u.d * inv / lc) : vec2(0.0);
    b.radial = u.radial * inv;
    b.s = u.s * inv;
    b.tint = u.tint * inv;
    b.rough = u.rough * inv;
    b.light = u.w > 0.0 ? u.light * inv : 1.0;
    b.occlusion = u.w > 0.0 ? u.occlusion * inv : 1.0;
    b.tests = tests;
    return b;
}

#endif
