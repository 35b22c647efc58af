"""The OSL twin of the GLSL traversal, as source text for :mod:`app.export.osl`.

One section per GLSL file, in include order, each a port line by line of its twin (named in its header) so
that a reader can hold the two side by side. The sections are plain OSL functions; the shader body that
wires them to Cycles' globals and closures is :data:`SHADER_BODY`. Differences from the GLSL that the
language forces, in one place:

* OSL functions cannot see shader parameters, so the parameters travel in a struct (``VfParams``) and the
  per-ring numbers (``VfRing``) are computed in the shader from them with ``ring_layout``'s formulas.
* OSL has no ``vec2``: 2D quantities are pairs of floats; no ``uint``: see the hash section.
* OSL's ``a / 0`` is 0, not infinity; every division here is guarded the same way the GLSL guards it, and
  the open slab below a fiber's length cut is its own function (``vf_below``) so no ``INF`` enters an
  arithmetic expression.
* Cycles' OSL uses fast-math ``asin``/``atan2`` (errors up to 4.5e-5 rad, more than the traversal's
  angular slack): the angles that pick candidates and place fibers go through ``vf_asin``/``vf_atan2``,
  refined by a Newton step on the accurate ``sin``/``cos`` (section TRIG).
* At most 64 chord pieces per curved-fiber arc (GLSL: 16): one object is a whole guide here, where the
  preview splits guides into short segments (section CURVED).
* No ``#if``: the variants (traversal mode, straight or shaped, thesis hash) are runtime branches on
  parameters, which Cycles' OSL optimizer folds away when the parameter is not connected.

Kept as Python strings (not ``.osl`` files) so that an installed vfiber exports without package data.
"""

from __future__ import annotations

HASH = r"""
// ---- hash (glsl/common/hash.glsl) --------------------------------------------------------------
// Per-fiber random numbers, bit-exact with glsl/common/hash.glsl and app/reference.py (tested by
// rendering them in Cycles). OSL's int is 32-bit two's complement: + and * wrap exactly like GLSL's
// uint, ^ is bitwise, but >> is an arithmetic shift, so every right shift masks off the copied sign
// bits. Constants above 0x7fffffff are written as the int32 with the same bits.
#define VF_CH_RADIAL 0
#define VF_CH_ANGULAR 1
#define VF_CH_LENGTH 2
#define VF_CH_TINT 3
#define VF_CH_ROUGH 4
#define VF_CH_CURL 5
#define VF_CH_RING 6

int vf_lowbias32(int x0)
{
    int x = x0;
    x = x ^ ((x >> 16) & 0xffff);
    x = x * 2146121005;             // 0x7feb352d
    x = x ^ ((x >> 15) & 0x1ffff);
    x = x * -2073254261;            // 0x846ca68b
    x = x ^ ((x >> 16) & 0xffff);
    return x;
}

int vf_fiber_key(int seed, int guide, int ring, int fiber)
{
    int h = vf_lowbias32(seed + -1640531527);   // seed + 0x9e3779b9
    h = vf_lowbias32(h ^ guide);
    h = vf_lowbias32(h ^ ring);
    return vf_lowbias32(h ^ fiber);
}

float vf_key_random(int key, int channel)
{
    return (float)((vf_lowbias32(key ^ channel) >> 8) & 0xffffff) * (1.0 / 16777216.0);
}

float vf_fiber_random(int seed, int guide, int ring, int fiber, int channel)
{
    return vf_key_random(vf_fiber_key(seed, guide, ring, fiber), channel);
}

float vf_thesis_random(float slotDeg, float ring, float channel)
{
    float y = 1207.523 * (slotDeg + 0.37 * channel + 0.11 * ring);
    return y - floor(y);
}
"""

TRIG = r"""
// ---- accurate inverse trigonometry -------------------------------------------------------------------
// Cycles compiles OSL with fast-math approximations (measured in Blender 5.0.1: asin is off by up to
// 4.5e-5, atan2 by 9e-6 radians, while sin, cos and sqrt are within a few float32 ulps). The traversal's
// candidate windows are only EPS_ANGLE = 2e-5 wider than the true angular reach, so the angles that choose
// candidates and place fibers are refined here by a Newton step on the accurate sin/cos.
float vf_asin(float x)
{
    float ax = min(abs(x), 1.0);
    // asin(ax) = pi/2 - 2 asin(sqrt((1 - ax) / 2)) above 0.5, so the Newton step never divides by ~0
    float a = ax > 0.5 ? sqrt(0.5 * (1.0 - ax)) : ax;
    float y = asin(a);
    y -= (sin(y) - a) / cos(y);
    float r = ax > 0.5 ? M_PI_2 - 2.0 * y : y;
    return x < 0.0 ? -r : r;
}

float vf_atan2(float y, float x)
{
    float t = atan2(y, x);
    float ct = cos(t);
    float st = sin(t);
    // the small angle from (cos t, sin t) to (x, y): tan(delta) = cross / dot
    float dt = x * ct + y * st;
    return dt > 0.0 ? t + (y * ct - x * st) / dt : t;
}
"""

PARAMS = r"""
// ---- parameters (what the GLSL reads from uniforms) ----------------------------------------------
#define VF_INF 1e38
#define VF_EPS_ANGLE 2e-5
#define VF_EPS_BOUND 1e-4
#define VF_MAX_RINGS 64
#define VF_MAX_SUB 64      // GLSL: 16 (see CURVED)

struct VfParams {
    int rings;
    float phiStep;
    float phiIncrement;
    float evenSpacing;
    float fiberRadius;      // unit space (fraction of the container radius)
    float radialJitter;
    float angularJitter;
    float lengthJitter;
    int thesisHash;
    int seed;
    int mode;               // 0 fast, 1 exact, 2 brute
    int shaped;
    float ellipsoid;
    float twist;
    int twistPattern;       // 0 uniform, 1 ramped, 2 alternating
    float curlAmplitude;    // unit space: shape.curl_amplitude / rings (app/render/renderer.py)
    float curlFrequency;
    int curlPattern;        // 0 helix, 1 wave
};

// The per-ring numbers the CPU computes in app/reference.py::ring_layout (uRingA, uRingB, uRingN).
struct VfRing {
    float rho;
    float dphi;
    float rot;
    float reach;
    float maxDr;
    float maxDphi;
    int n;
};
"""

LAYOUT = r"""
// ---- layout (glsl/fibers/layout.glsl; ring numbers: app/reference.py::ring_layout) ----------------
void vf_ring(VfParams p, int i, output VfRing R)
{
    float K = (float)p.rings;
    R.rho = 1.0 - ((float)i + 0.5) / K;
    float rho0 = 1.0 - 0.5 / K;
    float halfWidth = 0.5 / K;
    float stepDeg = (p.phiStep + (float)i * p.phiIncrement) * (1.0 + p.evenSpacing * (rho0 / R.rho - 1.0));
    R.n = max(1, (int)floor(360.0 / stepDeg + 0.5));
    R.dphi = M_2PI / (float)R.n;
    R.rot = p.thesisHash ? 0.0 : vf_fiber_random(p.seed, 0, i, 0, VF_CH_RING) * R.dphi;
    R.maxDr = max(0.0, halfWidth - p.fiberRadius) * p.radialJitter;
    float rhoMin = R.rho - R.maxDr;
    float disc = vf_asin(min(1.0, p.fiberRadius / rhoMin));
    R.maxDphi = max(0.0, 0.5 * R.dphi - disc) * p.angularJitter;
    // The CPU computes the reach in float64. In float32, rhoMin carries a rounding error that asin
    // magnifies without bound as fiberRadius / rhoMin nears 1 (a fiber that can touch the axis), so the
    // window uses the half-angle of a disc a few ulps larger: never narrower than the true reach.
    R.reach = R.maxDphi + vf_asin(min(1.0, p.fiberRadius / rhoMin * (1.0 + 1e-6)));
}

// The three random numbers that place a fiber: radial, angular, length.
void vf_placement_randoms(VfParams p, VfRing R, int guide, int ring, int j,
                          output float uR, output float uA, output float uL)
{
    if (p.thesisHash) {
        float slotDeg = degrees(R.rot + (float)j * R.dphi);
        uR = vf_thesis_random(slotDeg, (float)ring, (float)VF_CH_RADIAL);
        uA = vf_thesis_random(slotDeg, (float)ring, (float)VF_CH_ANGULAR);
        uL = vf_thesis_random(slotDeg, (float)ring, (float)VF_CH_LENGTH);
    } else {
        int key = vf_fiber_key(p.seed, guide, ring, j);
        uR = vf_key_random(key, VF_CH_RADIAL);
        uA = vf_key_random(key, VF_CH_ANGULAR);
        uL = vf_key_random(key, VF_CH_LENGTH);
    }
}

float vf_curl_phase(VfParams p, VfRing R, int guide, int ring, int j)
{
    if (p.thesisHash) {
        float slotDeg = degrees(R.rot + (float)j * R.dphi);
        return vf_thesis_random(slotDeg, (float)ring, (float)VF_CH_CURL);
    }
    return vf_key_random(vf_fiber_key(p.seed, guide, ring, j), VF_CH_CURL);
}

void vf_fiber_center(VfParams p, VfRing R, int guide, int ring, int j,
                     output float cx, output float cy, output float vEnd)
{
    float uR, uA, uL;
    vf_placement_randoms(p, R, guide, ring, j, uR, uA, uL);
    float radius = R.rho + (2.0 * uR - 1.0) * R.maxDr;
    float angle = R.rot + (float)j * R.dphi + (2.0 * uA - 1.0) * R.maxDphi;
    cx = radius * cos(angle);
    cy = radius * sin(angle);
    vEnd = 1.0 - p.lengthJitter * uL;
}
"""

INTERVALS = r"""
// ---- intervals (glsl/geometry/intervals.glsl) -----------------------------------------------------
// Ray interval inside the infinite vertical cylinder of radius r about (cx, cy); empty when t0 > t1.
// Stable roots (pbrt) with the cancellation-free discriminant (sqrt(a) r - |cross|)(sqrt(a) r + |cross|).
void vf_circle_interval(float ox, float oy, float dx, float dy, float cx, float cy, float r,
                        output float t0, output float t1)
{
    float ocx = ox - cx;
    float ocy = oy - cy;
    float a = dx * dx + dy * dy;
    float b = ocx * dx + ocy * dy;
    float len = sqrt(ocx * ocx + ocy * ocy);
    float cc = (len - r) * (len + r);
    if (a == 0.0) {
        t0 = cc <= 0.0 ? -VF_INF : VF_INF;
        t1 = cc <= 0.0 ? VF_INF : -VF_INF;
        return;
    }
    float cross2 = abs(ocx * dy - ocy * dx);
    float ra = sqrt(a) * r;
    float disc = (ra - cross2) * (ra + cross2);
    if (disc < 0.0) {
        t0 = VF_INF;
        t1 = -VF_INF;
        return;
    }
    float q = -(b + (b >= 0.0 ? 1.0 : -1.0) * sqrt(disc));
    float ta = q / a;
    float tb = q != 0.0 ? cc / q : ta;
    t0 = min(ta, tb);
    t1 = max(ta, tb);
}

// lo <= o + t d <= hi
void vf_slab(float o, float d, float lo, float hi, output float t0, output float t1)
{
    if (d == 0.0) {
        int inside = o >= lo && o <= hi;
        t0 = inside ? -VF_INF : VF_INF;
        t1 = inside ? VF_INF : -VF_INF;
        return;
    }
    float ta = (lo - o) / d;
    float tb = (hi - o) / d;
    t0 = min(ta, tb);
    t1 = max(ta, tb);
}

// o + t d <= hi: the GLSL's slab(o, d, -INF, hi), with no infinity in the arithmetic.
void vf_below(float o, float d, float hi, output float t0, output float t1)
{
    if (hi >= VF_INF) {
        t0 = -VF_INF;
        t1 = VF_INF;
        return;
    }
    if (d == 0.0) {
        t0 = o <= hi ? -VF_INF : VF_INF;
        t1 = o <= hi ? VF_INF : -VF_INF;
        return;
    }
    float tc = (hi - o) / d;
    t0 = d > 0.0 ? -VF_INF : tc;
    t1 = d > 0.0 ? tc : VF_INF;
}
"""

CONTAINER = r"""
// ---- container and unit space (glsl/geometry/container.glsl) --------------------------------------
// One container per object: the object frame is the container's local frame (origin p0, +Z along the
// axis to p1), straight, with caps perpendicular to the axis (joint normals n0 = n1 = +Z), so that
// joint_slope() is 0 and the bounding slab is [0, h]. Unit space: P' = P_local / w(z), w = r0 + kappa z.
struct VfSeg {
    float h;
    float r0;
    float kappa;
    float v0;
    float v1;
    int guide;
    float zLo;
    float zHi;
    float rBound;
};

struct VfRay {
    float tb;       // ray parameter of the unit-space origin
    vector o;       // local origin at tb
    vector d;       // local unit direction
    float wO;
    vector O;       // unit-space origin
    vector D;       // unit-space unit direction
    float Dlen;
    float s0;       // inside the container
    float s1;
};

void vf_make_segment(float radius, float len, float taper, int guide, output VfSeg seg)
{
    seg.h = len;
    seg.r0 = radius;
    seg.v0 = 0.0;
    seg.v1 = 1.0;
    float r1 = radius * (1.0 - taper * (seg.v1 - seg.v0));
    seg.kappa = (r1 - radius) / len;
    seg.guide = guide;
    seg.rBound = max(radius, r1);
    seg.zLo = 0.0;      // -rBound * joint_slope(n0), n0 = +Z
    seg.zHi = len;      // h + rBound * joint_slope(n1), n1 = +Z
}

// Clip [s0, s1] to the half-space m . P <= c.
void vf_clip_half_space(vector O, vector D, vector m, float c, output float s0, output float s1)
{
    float mo = dot(O, m) - c;
    float md = dot(D, m);
    if (md == 0.0) {
        if (mo > 0.0)
            s1 = -VF_INF;
        return;
    }
    float tp = -mo / md;
    if (md < 0.0)
        s0 = max(s0, tp);
    else
        s1 = min(s1, tp);
}

int vf_to_unit_space(VfSeg seg, point ro, vector rd, float tNear, output VfRay ur)
{
    vector o = vector(ro);
    vector d = rd;
    // bounding cylinder and slab first: cheap, conservative, and a region where w(z) > 0
    float c0, c1, z0, z1;
    vf_circle_interval(o[0], o[1], d[0], d[1], 0.0, 0.0, seg.rBound * (1.0 + VF_EPS_BOUND), c0, c1);
    vf_slab(o[2], d[2], seg.zLo, seg.zHi, z0, z1);
    float tb0 = max(max(c0, z0), tNear);
    float tb1 = min(c1, z1);
    if (!(tb0 <= tb1))
        return 0;
    ur.tb = tb0;
    ur.o = o + tb0 * d;
    ur.d = d;
    ur.wO = seg.r0 + seg.kappa * ur.o[2];
    ur.O = ur.o / ur.wO;
    vector D = d * ur.wO - ur.o * (seg.kappa * d[2]);
    ur.Dlen = length(D);
    ur.D = D / ur.Dlen;
    // the container in unit space: unit cylinder, root cap, tip cap
    float s0, s1;
    vf_circle_interval(ur.O[0], ur.O[1], ur.D[0], ur.D[1], 0.0, 0.0, 1.0, s0, s1);
    s0 = max(s0, 0.0);
    vf_clip_half_space(ur.O, ur.D, vector(0.0, 0.0, -seg.r0), 0.0, s0, s1);
    vf_clip_half_space(ur.O, ur.D, vector(0.0, 0.0, seg.r0 + seg.h * seg.kappa), seg.h, s0, s1);
    ur.s0 = s0;
    ur.s1 = s1;
    return s0 <= s1;
}

// Guide parameter at unit-space height zUnit (the projective map inverted along the axis).
float vf_unit_to_v(VfSeg seg, float zUnit)
{
    float z = seg.r0 * zUnit / (1.0 - seg.kappa * zUnit);
    return seg.v0 + (seg.v1 - seg.v0) * z / seg.h;
}

float vf_z_cut_unit(VfSeg seg, float vEnd)
{
    if (vEnd >= seg.v1)
        return VF_INF;
    if (vEnd <= seg.v0)
        return -VF_INF;
    float z = (vEnd - seg.v0) / (seg.v1 - seg.v0) * seg.h;
    return z / (seg.r0 + seg.kappa * z);
}
"""

SHAPE = r"""
// ---- shape (glsl/fibers/shape.glsl) ------------------------------------------------------------------
// c(v) = E(v) R(tau(v)) rest + curl(v), v the guide parameter (0 root .. 1 tip).
float vf_shape_twist(VfParams p, float gv, int ring)
{
    float t = p.twistPattern == 1 ? gv * gv : gv;
    float sgn = (p.twistPattern == 2 && (ring & 1) == 1) ? -1.0 : 1.0;
    return sgn * M_2PI * p.twist * t;
}

void vf_twist_range(VfParams p, float va, float vb, int ring, output float lo, output float hi)
{
    float a = vf_shape_twist(p, va, ring);
    float b = vf_shape_twist(p, vb, ring);
    lo = min(a, b);
    hi = max(a, b);
}

float vf_shape_scale(VfParams p, float gv)
{
    float x = p.ellipsoid * (2.0 * gv - 1.0);
    return sqrt(max(0.0, 1.0 - x * x));
}

void vf_fiber_center_at(VfParams p, float restX, float restY, float gv, int ring, float curlPhase,
                        output float cx, output float cy)
{
    float tau = vf_shape_twist(p, gv, ring);
    float ct = cos(tau);
    float st = sin(tau);
    float e = vf_shape_scale(p, gv);
    cx = e * (ct * restX - st * restY);
    cy = e * (st * restX + ct * restY);
    if (p.curlAmplitude > 0.0) {
        float a = M_2PI * (p.curlFrequency * gv + curlPhase);
        if (p.curlPattern == 0) {
            cx += p.curlAmplitude * cos(a);
            cy += p.curlAmplitude * sin(a);
        } else {
            float len = sqrt(cx * cx + cy * cy);
            float ax = len > 0.0 ? -cy / len : 1.0;
            float ay = len > 0.0 ? cx / len : 0.0;
            float sw = p.curlAmplitude * sin(a);
            cx += sw * ax;
            cy += sw * ay;
        }
    }
}
"""

CURVED = r"""
// ---- curved fibers (glsl/fibers/curved.glsl) -------------------------------------------------------
// The one change: at most VF_MAX_SUB = 64 chord pieces per arc where the GLSL allows 16. The preview
// splits a guide into segments (and must stay under llvmpipe's loop cap); here one object is a whole
// guide, so an arc can span the guide's full height and needs more pieces for the same 0.1 fiber radius
// accuracy. The count is adaptive: arcs that need few pieces get few.
// Chord pieces needed over a height span dv so the chord stays within 0.1 fiber radius of the curve.
int vf_chord_pieces(VfParams p, VfRing R, float dv, float eLo)
{
    float rho = R.rho + R.maxDr;
    float curl = p.curlAmplitude * pow(M_2PI * p.curlFrequency, 2.0);
    float twistRate = M_2PI * abs(p.twist) * (p.twistPattern == 1 ? 2.0 : 1.0);
    float twist = rho * twistRate * twistRate;
    float ell = rho * 4.0 * p.ellipsoid * p.ellipsoid / pow(max(eLo, 0.25), 3.0);
    float bend = curl + twist + ell;            // a bound on |c''(v)|
    if (bend <= 0.0)
        return 1;
    float dvMax = sqrt(0.8 * max(p.fiberRadius, 1e-30) / bend);
    // clamped as a float first: int() of a huge ratio is undefined
    return clamp((int)ceil(min(dv / dvMax, (float)VF_MAX_SUB)), 1, VF_MAX_SUB);
}

float vf_curved_fiber_test(VfParams p, VfRing R, VfSeg seg, VfRay ur, float restX, float restY,
                           float curlPhase, int ring, float vEnd, float eLo, float sA, float sB,
                           output int kind)
{
    kind = 0;
    float zc = vf_z_cut_unit(seg, vEnd);
    if (zc == -VF_INF)
        return VF_INF;
    float zs0, zs1;
    vf_below(ur.O[2], ur.D[2], zc, zs0, zs1);
    float a = max(max(sA, ur.s0), zs0);
    float b = min(min(sB, ur.s1), zs1);
    if (!(a <= b))
        return VF_INF;
    float va = vf_unit_to_v(seg, ur.O[2] + a * ur.D[2]);
    float vb = vf_unit_to_v(seg, ur.O[2] + b * ur.D[2]);
    int n = vf_chord_pieces(p, R, abs(vb - va), eLo);
    float stp = (b - a) / (float)n;
    float pcx, pcy;
    vf_fiber_center_at(p, restX, restY, va, ring, curlPhase, pcx, pcy);
    for (int k = 0; k < n; k++) {
        float sk = a + (float)k * stp;
        float sk1 = k == n - 1 ? b : sk + stp;
        float ncx, ncy;
        vf_fiber_center_at(p, restX, restY, vf_unit_to_v(seg, ur.O[2] + sk1 * ur.D[2]), ring, curlPhase,
                           ncx, ncy);
        float len = sk1 - sk;
        // the ray seen from the fiber's chord: a point moving at D.xy - (chord velocity)
        float q0x = ur.O[0] + sk * ur.D[0] - pcx;
        float q0y = ur.O[1] + sk * ur.D[1] - pcy;
        float dqx = len > 0.0 ? ur.D[0] - (ncx - pcx) / len : ur.D[0];
        float dqy = len > 0.0 ? ur.D[1] - (ncy - pcy) / len : ur.D[1];
        float e0, e1;
        vf_circle_interval(q0x, q0y, dqx, dqy, 0.0, 0.0, p.fiberRadius, e0, e1);
        float lo = max(e0, 0.0);
        float hi = min(e1, len);
        if (lo <= hi) {
            if (k == 0 && lo == 0.0)
                kind = a == zs0 ? 1 : 2;    // entered through the tip or a boundary
            return sk + lo;
        }
        pcx = ncx;
        pcy = ncy;
    }
    return VF_INF;
}
"""

TRAVERSE = r"""
// ---- traversal (glsl/fibers/traverse.glsl) -----------------------------------------------------------
struct VfHit {
    float s;        // unit-space parameter, VF_INF on a miss
    int ring;
    int fiber;
    int kind;       // 0 fiber side, 1 fiber tip (length cut), 2 container boundary
    float cx;       // fiber centre in unit space
    float cy;
    float dcx;      // how the centre moves with the guide parameter (0 when straight)
    float dcy;
};

void vf_no_hit(output VfHit h)
{
    h.s = VF_INF;
    h.ring = -1;
    h.fiber = -1;
    h.kind = 0;
    h.cx = 0.0;
    h.cy = 0.0;
    h.dcx = 0.0;
    h.dcy = 0.0;
}

// One straight fiber: a capped vertical cylinder about (cx, cy), from the root plane to its length cut,
// inside the container interval. Returns the entry parameter or VF_INF.
float vf_fiber_test(VfParams p, VfSeg seg, VfRay ur, float cx, float cy, float vEnd, output int kind)
{
    kind = 0;
    float zc = vf_z_cut_unit(seg, vEnd);
    if (zc == -VF_INF)
        return VF_INF;
    float c0, c1, z0, z1;
    vf_circle_interval(ur.O[0], ur.O[1], ur.D[0], ur.D[1], cx, cy, p.fiberRadius, c0, c1);
    vf_below(ur.O[2], ur.D[2], zc, z0, z1);
    float sIn = max(max(c0, z0), ur.s0);
    float sOut = min(min(c1, z1), ur.s1);
    if (!(sIn <= sOut))
        return VF_INF;
    kind = sIn == c0 ? 0 : (sIn == z0 ? 1 : 2);
    return sIn;
}

void vf_test_fiber(VfParams p, VfRing R, VfSeg seg, VfRay ur, int ring, int j, output VfHit best)
{
    float cx, cy, vEnd;
    vf_fiber_center(p, R, seg.guide, ring, j, cx, cy, vEnd);
    int kind = 0;
    float s = vf_fiber_test(p, seg, ur, cx, cy, vEnd, kind);
    // ties go to the lower (ring, fiber), the order brute force tests them in
    int tie = s == best.s && (ring < best.ring || (ring == best.ring && j < best.fiber));
    if (s < best.s || (tie && s < VF_INF)) {
        best.s = s;
        best.ring = ring;
        best.fiber = j;
        best.kind = kind;
        best.cx = cx;
        best.cy = cy;
    }
}

float vf_wrap_pi(float a)
{
    return a - 6.28318530718 * floor((a + 3.14159265359) / 6.28318530718);
}

// Test the candidates of ring i on the piece [sA, sB] of the ray. Returns 1 when traversal is over.
int vf_visit_piece(VfParams p, VfSeg seg, VfRay ur, int i, float sA0, float sB0, output VfHit best)
{
    float sA = max(sA0, ur.s0);
    float sB = min(sB0, ur.s1);
    if (!(sA <= sB))
        return 0;                       // this stretch lies outside the container (caps)
    if (sA >= best.s)
        return 1;                       // pieces come in ray order: nothing later can be nearer
    float pAx = ur.O[0] + sA * ur.D[0];
    float pAy = ur.O[1] + sA * ur.D[1];
    float pBx = ur.O[0] + sB * ur.D[0];
    float pBy = ur.O[1] + sB * ur.D[1];
    // a piece can touch the axis only at one end (a ray through the axis); take the other end's angle
    float thA = (pAx * pAx + pAy * pAy) > 0.0 ? vf_atan2(pAy, pAx) : vf_atan2(pBy, pBx);
    float thB = (pBx * pBx + pBy * pBy) > 0.0 ? vf_atan2(pBy, pBx) : thA;
    float span = vf_wrap_pi(thB - thA);
    VfRing R;
    vf_ring(p, i, R);
    float reach = R.reach + VF_EPS_ANGLE;
    int n = R.n;
    int dir = span >= 0.0 ? 1 : -1;
    float first = (thA - (float)dir * reach - R.rot) / R.dphi;
    float last = (thA + span + (float)dir * reach - R.rot) / R.dphi;
    int j0 = dir > 0 ? (int)ceil(first) : (int)floor(first);
    int j1 = dir > 0 ? (int)floor(last) : (int)ceil(last);
    int count = min(max(0, (j1 - j0) * dir + 1), n);
    for (int k = 0; k < count; k++) {
        int j = j0 + k * dir;
        j -= n * (int)floor((float)j / (float)n);     // into [0, n)
        vf_test_fiber(p, R, seg, ur, i, j, best);
        if (p.mode == 0 && best.s < VF_INF)
            return 1;                   // fast: the first fiber found wins
    }
    return 0;
}

void vf_traverse_straight(VfParams p, VfSeg seg, VfRay ur, output VfHit best)
{
    vf_no_hit(best);
    int K = p.rings;
    if (p.mode == 2) {                  // brute: every fiber of every ring
        for (int i = 0; i < K; i++) {
            VfRing R;
            vf_ring(p, i, R);
            for (int j = 0; j < R.n; j++)
                vf_test_fiber(p, R, seg, ur, i, j, best);
        }
        return;
    }
    float o2x = ur.O[0];
    float o2y = ur.O[1];
    float d2x = ur.D[0];
    float d2y = ur.D[1];
    float a = d2x * d2x + d2y * d2y;
    float backA[VF_MAX_RINGS];          // thesis 3.11: back arcs, pushed outer to inner
    float backB[VF_MAX_RINGS];
    float outA, outB;
    vf_circle_interval(o2x, o2y, d2x, d2y, 0.0, 0.0, 1.0, outA, outB);
    int deepest = K - 1;
    for (int i = 0; i < K - 1; i++) {
        float inA, inB;
        vf_circle_interval(o2x, o2y, d2x, d2y, 0.0, 0.0, 1.0 - (float)(i + 1) / (float)K, inA, inB);
        if (inA > inB) {                // the path stays in this ring: deepest reached
            deepest = i;
            break;
        }
        if (vf_visit_piece(p, seg, ur, i, outA, inA, best))
            return;
        backA[i] = inB;
        backB[i] = outB;
        outA = inA;
        outB = inB;
    }
    // deepest ring: one stretch, split where the path comes closest to the axis
    float sMid = a > 0.0 ? -(o2x * d2x + o2y * d2y) / a : ur.s0;
    if (vf_visit_piece(p, seg, ur, deepest, outA, sMid, best))
        return;
    if (vf_visit_piece(p, seg, ur, deepest, sMid, outB, best))
        return;
    for (int i = deepest - 1; i >= 0; i--) {
        if (vf_visit_piece(p, seg, ur, i, backA[i], backB[i], best))
            return;
    }
}

// --- curved fibers: bands that hold each ring's fibers at every height of the segment ---------------
void vf_segment_bands(VfParams p, VfSeg seg, output float eLo, output float eHi)
{
    float vLo = vf_unit_to_v(seg, seg.zLo / (seg.r0 + seg.kappa * seg.zLo));
    float vHi = vf_unit_to_v(seg, seg.zHi / (seg.r0 + seg.kappa * seg.zHi));
    float ea = vf_shape_scale(p, vLo);
    float eb = vf_shape_scale(p, vHi);
    eLo = min(ea, eb);
    eHi = (min(vLo, vHi) <= 0.5 && max(vLo, vHi) >= 0.5) ? 1.0 : max(ea, eb);
}

void vf_ring_band(VfParams p, VfRing R, float eLo, float eHi, output float inner, output float outer)
{
    float grow = p.fiberRadius + p.curlAmplitude + 1e-6;
    inner = max(0.0, eLo * (R.rho - R.maxDr) - grow);
    outer = eHi * (R.rho + R.maxDr) + grow;
}

float vf_shaped_reach(VfParams p, VfRing R, float eLo)
{
    float dMin = eLo * (R.rho - R.maxDr);
    float r = p.fiberRadius + p.curlAmplitude;
    float disc = dMin > r ? vf_asin(min(1.0, r / dMin * (1.0 + 1e-6))) : 3.14159265359;   // see vf_ring
    return R.maxDphi + disc + VF_EPS_ANGLE;
}

// Test ring i's candidates on the arc [sA, sB]; in brute mode every fiber of the ring. 1: done.
int vf_visit_shaped(VfParams p, VfSeg seg, VfRay ur, int i, float sA, float sB, float eLo,
                    output VfHit best)
{
    float a = max(sA, ur.s0);
    float b = min(sB, ur.s1);
    if (!(a <= b))
        return 0;
    if (p.mode != 2 && a >= best.s)
        return 1;
    VfRing R;
    vf_ring(p, i, R);
    int n = R.n;
    int j0 = 0;
    int count = n;
    int dir = 1;
    if (p.mode != 2) {
        float pAx = ur.O[0] + a * ur.D[0];
        float pAy = ur.O[1] + a * ur.D[1];
        float pBx = ur.O[0] + b * ur.D[0];
        float pBy = ur.O[1] + b * ur.D[1];
        float thA = (pAx * pAx + pAy * pAy) > 0.0 ? vf_atan2(pAy, pAx) : vf_atan2(pBy, pBx);
        float thB = (pBx * pBx + pBy * pBy) > 0.0 ? vf_atan2(pBy, pBx) : thA;
        float span = vf_wrap_pi(thB - thA);
        float twLo, twHi;
        vf_twist_range(p, vf_unit_to_v(seg, ur.O[2] + a * ur.D[2]), vf_unit_to_v(seg, ur.O[2] + b * ur.D[2]),
                       i, twLo, twHi);
        float reach = vf_shaped_reach(p, R, eLo);
        dir = span >= 0.0 ? 1 : -1;
        float first = dir > 0 ? thA - twHi - reach : thA - twLo + reach;
        float last = dir > 0 ? thA + span - twLo + reach : thA + span - twHi - reach;
        first = (first - R.rot) / R.dphi;
        last = (last - R.rot) / R.dphi;
        j0 = dir > 0 ? (int)ceil(first) : (int)floor(first);
        int j1 = dir > 0 ? (int)floor(last) : (int)ceil(last);
        count = min(max(0, (j1 - j0) * dir + 1), n);
    }
    for (int k = 0; k < count; k++) {
        int j = j0 + k * dir;
        j -= n * (int)floor((float)j / (float)n);
        float restX, restY, vEnd;
        vf_fiber_center(p, R, seg.guide, i, j, restX, restY, vEnd);
        float phase = vf_curl_phase(p, R, seg.guide, i, j);
        int kind = 0;
        float s = vf_curved_fiber_test(p, R, seg, ur, restX, restY, phase, i, vEnd, eLo, a, b, kind);
        int tie = s == best.s && (i < best.ring || (i == best.ring && j < best.fiber));
        if (s < best.s || (tie && s < VF_INF)) {
            best.s = s;
            best.ring = i;
            best.fiber = j;
            best.kind = kind;
            float gv = vf_unit_to_v(seg, ur.O[2] + s * ur.D[2]);
            vf_fiber_center_at(p, restX, restY, gv, i, phase, best.cx, best.cy);
            float ax, ay, bx, by;
            vf_fiber_center_at(p, restX, restY, gv + 1e-3, i, phase, ax, ay);
            vf_fiber_center_at(p, restX, restY, gv - 1e-3, i, phase, bx, by);
            best.dcx = (ax - bx) / 2e-3;
            best.dcy = (ay - by) / 2e-3;
        }
        if (p.mode == 0 && best.s < VF_INF)
            return 1;
    }
    return 0;
}

// Arcs in order of where they start: fronts of the bands crossed twice (outer to inner), first halves
// of the bands crossed once, their second halves, then the backs (inner to outer).
void vf_traverse_shaped(VfParams p, VfSeg seg, VfRay ur, output VfHit best)
{
    vf_no_hit(best);
    float eLo, eHi;
    vf_segment_bands(p, seg, eLo, eHi);
    float o2x = ur.O[0];
    float o2y = ur.O[1];
    float d2x = ur.D[0];
    float d2y = ur.D[1];
    float a = d2x * d2x + d2y * d2y;
    float sMid = a > 0.0 ? -(o2x * d2x + o2y * d2y) / a : ur.s0;
    float backA[VF_MAX_RINGS];          // back arcs of the bands crossed twice
    float backB[VF_MAX_RINGS];
    float halves[VF_MAX_RINGS];         // where the second half of a band crossed once ends
    int nTwice = 0;
    int nOnce = 0;
    for (int i = 0; i < p.rings; i++) {
        VfRing R;
        vf_ring(p, i, R);
        float inner, outer;
        vf_ring_band(p, R, eLo, eHi, inner, outer);
        float oA, oB, iA, iB;
        vf_circle_interval(o2x, o2y, d2x, d2y, 0.0, 0.0, outer, oA, oB);
        if (oA > oB)
            break;                      // this band and every inner one are missed
        vf_circle_interval(o2x, o2y, d2x, d2y, 0.0, 0.0, inner, iA, iB);
        if (iA <= iB && nOnce == 0) {
            if (vf_visit_shaped(p, seg, ur, i, oA, iA, eLo, best))
                return;
            backA[nTwice] = iB;
            backB[nTwice] = oB;
            nTwice += 1;
        } else {
            if (vf_visit_shaped(p, seg, ur, i, oA, sMid, eLo, best))
                return;
            halves[nOnce] = oB;
            nOnce += 1;
        }
    }
    for (int k = 0; k < nOnce; k++) {
        if (vf_visit_shaped(p, seg, ur, nTwice + k, sMid, halves[k], eLo, best))
            return;
    }
    for (int i = nTwice - 1; i >= 0; i--) {
        if (vf_visit_shaped(p, seg, ur, i, backA[i], backB[i], eLo, best))
            return;
    }
}

void vf_traverse(VfParams p, VfSeg seg, VfRay ur, output VfHit best)
{
    if (p.shaped)
        vf_traverse_shaped(p, seg, ur, best);
    else
        vf_traverse_straight(p, seg, ur, best);
}
"""

HAIR = r"""
// ---- colour: Cycles' Principled Hair BSDF conversions (node_principled_hair_bsdf.osl, Blender 5.0) ----
color vf_sigma_from_concentration(float eumelanin, float pheomelanin)
{
    return eumelanin * color(0.506, 0.841, 1.653) + pheomelanin * color(0.343, 0.733, 1.924);
}

float vf_roughness_fac(float azimuthalRoughness)
{
    float x = azimuthalRoughness;
    return (((((0.245 * x) + 5.574) * x - 10.73) * x + 2.532) * x - 0.215) * x + 5.969;
}

color vf_sigma_from_reflectance(color c, float azimuthalRoughness)
{
    color sigma = color(log(c[0]), log(c[1]), log(c[2])) / vf_roughness_fac(azimuthalRoughness);
    return sigma * sigma;
}

// "Melanin concentration" parametrization: melanin in 0..1 mapped to 0..inf, split by redness.
color vf_sigma_from_melanin(float melanin, float redness)
{
    float m = -log(max(1.0 - melanin, 0.0001));
    return vf_sigma_from_concentration(m * (1.0 - redness), m * redness);
}

// The colour whose "Direct coloring" absorption is sigma (sigma_from_reflectance inverted).
color vf_reflectance_from_sigma(color sigma, float azimuthalRoughness)
{
    float f = vf_roughness_fac(azimuthalRoughness);
    return color(exp(-sqrt(sigma[0]) * f), exp(-sqrt(sigma[1]) * f), exp(-sqrt(sigma[2]) * f));
}
"""

#: the library, in include order
LIBRARY = (HASH, TRIG, PARAMS, LAYOUT, INTERVALS, CONTAINER, SHAPE, CURVED, TRAVERSE, HAIR)

SHADER_BODY = r"""
{
    // ---- the ray in the container's frame -------------------------------------------------------
    // Cycles 5.0: I points from P toward the viewer (app/export/blender.py), so the ray runs along -I.
    // P lies on the mesh's flat facets; the traversal intersects the analytic (round) container itself.
    vector dirObject = transform("object", vector(-I));
    float dirScale = length(dirObject);
    vector rd = dirObject / dirScale;
    point ro = transform("object", P);
    // A camera ray starts outside every container, so the whole line through it counts (also after it
    // has passed transparent surfaces). Other rays (shadow, bounce) start on a surface: only what lies
    // ahead of their origin can block them.
    float tNear = -VF_INF;
    float rayLength = 0.0;
    if (!raytype("camera") && getattribute("path:ray_length", rayLength))
        tNear = -rayLength * dirScale;

    // ---- this container: per-object attributes when the mesh has them, else the parameters -------
    float radius = scene_radius;
    float len = scene_length;
    float attr = 0.0;
    if (getattribute("vf_radius", attr) && attr > 0.0)
        radius = attr;
    if (getattribute("vf_length", attr) && attr > 0.0)
        len = attr;
    int guide = 0;
    if (getattribute("vf_index", attr))
        guide = (int)floor(attr + 0.5);
    else if (getattribute("object:random", attr))
        guide = (int)floor(attr * 16777216.0);     // a different fiber pattern per object, no set-up

    VfParams p;
    p.rings = fibers_rings;
    p.phiStep = fibers_phi_step;
    p.phiIncrement = fibers_phi_increment;
    p.evenSpacing = fibers_even_spacing;
    p.fiberRadius = fibers_fiber_radius;
    p.radialJitter = fibers_radial_jitter;
    p.angularJitter = fibers_angular_jitter;
    p.lengthJitter = fibers_length_jitter;
    p.thesisHash = fibers_hash == 1;
    p.seed = fibers_seed;
    p.mode = quality_mode;
    p.ellipsoid = shape_ellipsoid;
    p.twist = shape_twist;
    p.twistPattern = shape_twist_pattern;
    p.curlAmplitude = shape_curl_amplitude / (float)fibers_rings;
    p.curlFrequency = shape_curl_frequency;
    p.curlPattern = shape_curl_pattern;
    p.shaped = p.ellipsoid > 0.0 || p.curlAmplitude > 0.0 || p.twist != 0.0;

    VfSeg seg;
    vf_make_segment(radius, len, scene_taper, guide, seg);
    VfRay ur;
    if (p.rings < 1 || p.fiberRadius <= 0.0 || !vf_to_unit_space(seg, ro, rd, tNear, ur)) {
        BSDF = transparent();
        return;
    }
    VfHit hit;
    vf_traverse(p, seg, ur, hit);
    Hit = hit.s < VF_INF;
    Ring = hit.ring;
    Fiber = hit.fiber;
    Guide = guide;
    if (hit.s >= VF_INF) {
        BSDF = transparent();           // no fiber on this ray: look through the container
        return;
    }
    if (debug_view == 1) {              // ids as exact colours: ring, fiber, guide + 1
        BSDF = emission() * color((float)hit.ring, (float)hit.fiber, (float)(guide + 1));
        return;
    }

    // ---- the fiber's normal and tangent (glsl/stages/container.frag) --------------------------------
    vector Pu = ur.O + hit.s * ur.D;    // unit space
    vector nLocal;
    if (hit.kind == 0) {
        float rx = Pu[0] - hit.cx;
        float ry = Pu[1] - hit.cy;
        nLocal = vector(rx, ry, -seg.kappa * (rx * Pu[0] + ry * Pu[1]));
    } else if (hit.kind == 1) {
        nLocal = vector(0.0, 0.0, 1.0);
    } else {
        nLocal = -ur.d;                 // a fiber cut by a cap: its section faces us
    }
    normal Nf = normalize(transform("object", "world", normal(nLocal)));
    float wHit = seg.r0 / (1.0 - seg.kappa * Pu[2]);
    float dvdz = (seg.v1 - seg.v0) / seg.h;
    vector Tf = normalize(transform("object", "world",
                                    vector(seg.kappa * hit.cx + wHit * hit.dcx * dvdz,
                                           seg.kappa * hit.cy + wHit * hit.dcy * dvdz, 1.0)));
    if (dot(Nf, I) < 0.0)
        Nf = -Nf;                       // face the viewer (I points toward it in Cycles)

    // ---- per-fiber colour and roughness: the preview's variation, Principled Hair's conversions -----
    float tint = vf_fiber_random(fibers_seed, guide, hit.ring, hit.fiber, VF_CH_TINT) - 0.5;
    float rough = vf_fiber_random(fibers_seed, guide, hit.ring, hit.fiber, VF_CH_ROUGH) - 0.5;
    float roughFactor = 1.0 + look_roughness_variation * 2.0 * rough;   // Principled: Random Roughness
    float roughness = clamp(look_roughness * roughFactor, 0.02, 1.0);
    float radialRoughness = clamp(cycles_radial_roughness * roughFactor, 0.001, 1.0);
    color sigma;
    color albedo;
    if (look_color_mode == 1) {         // melanin, with Principled's Random Color on the concentration
        sigma = vf_sigma_from_melanin(look_melanin * (1.0 + look_tint_variation * 2.0 * tint),
                                      look_melanin_redness);
        albedo = vf_reflectance_from_sigma(sigma, radialRoughness);
    } else {                            // a colour: Principled's "Direct coloring"
        albedo = clamp(look_color * (1.0 + look_tint_variation * 2.0 * tint), color(1e-4), color(1.0));
        sigma = vf_sigma_from_reflectance(albedo, radialRoughness);
    }
    // density self-shadowing of the preview; "traced" leaves it to Cycles' own shadow rays
    float depthIn = 1.0 - sqrt(hit.cx * hit.cx + hit.cy * hit.cy);
    float occlusion = look_self_shadow == 1 ? mix(1.0, exp(-3.0 * depthIn), look_shadow_density) : 1.0;

    if (look_model == 1) {
        // marschner: Cycles' Principled Hair (Chiang). Cycles takes this closure's frame from the mesh
        // (dPdu, Ng), not from Nf: see docs/osl.md.
        BSDF = occlusion * hair_chiang(Nf, sigma, roughness, radialRoughness, 1.0 - clamp(cycles_coat, 0.0, 1.0),
                                       radians(cycles_offset), cycles_ior);
    } else {
        // kajiya_kay: the preview's lobes on the fiber's own tangent: a diffuse term, a white primary
        // highlight shifted toward the root and a tinted, wider secondary one toward the tip.
        BSDF = occlusion * (albedo * diffuse(Nf)
                            + 0.25 * hair_reflection(Nf, roughness, roughness, Tf, -0.1)
                            + 0.4 * albedo * hair_reflection(Nf, 1.4 * roughness, 1.4 * roughness, Tf, 0.15));
    }
}
"""
