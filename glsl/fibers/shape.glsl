// shape.glsl: fibers that are not straight pins (thesis 3.10, Figures 26-34).
//   vec2  fiber_center_at(vec2 rest, float v, int ring, float curlPhase)   unit-space centre at height v
//   float shape_twist(float v, int ring)     rotation of the pattern about the axis, radians
//   float shape_scale(float v)               ellipsoid: radial scale of every ring at height v
//   RingPoint ring_point(Segment seg, UnitRay ur, float s, int ring)   the ray at s, seen in the ring's frame
//   vec2  ring_frame_center(vec2 rest, CurlTurn curl, RingPoint P)      a fiber's centre in that frame
//   Frizz frizz_of(float curlPhase); vec2 frizz_offset(Frizz f, float v)  frizz and noise, ring's frame
//   float shape_displacement()               the most the curl, frizz and noise move a fiber together
// v is the guide parameter (0 root .. 1 tip). A fiber's centre at height v is its rest position scaled by
// the ellipsoid, rotated by the twist, plus the curl offset and the frizz (frizz and noise), which sways
// along a direction fixed in the ring's turning frame:
//   c(v) = E(v) R(tau(v)) rest + curl(v) + R(tau(v)) frizz(v)
// Ellipsoid: rings follow x^2 + y^2 = r^2 (1 - e^2 (2v - 1)^2): e = 0 is the cylinder (a degenerate
// ellipsoid), e = 1 the ellipsoid inscribed in the guide's length.
// Twist patterns: 0 uniform tau = 2 pi T v, 1 ramped tau = 2 pi T v^2, 2 alternating: the sign flips
// ring by ring. Curl patterns: 0 helix (a circle about the rest line), 1 wave (a sway along the ring).
// The ring's frame turns with the twist: R(-tau(v)) applied at every height. There a fiber's centre is
//   c'(v) = E(v) rest + R(-tau(v)) curl(v)
// whose angle about the axis stays within the curl's reach of the rest angle: a twisted fiber is straight
// in it, and the ray, whose distance to the axis the rotation keeps, is the curve that turns.
// Twin: app/fibers/shape.py (fiber_center_at, shape_twist, shape_scale, frizz_randoms, frizz_offset,
// Shape.displacement), app/reference.py (ring_point,
// ring_frame_center). The pattern codes are app/fibers/shape.py's, injected (app.fibers.glsl_defines).

#include "geometry/container.glsl"
#include "common/hash.glsl"

#ifndef FIBERS_SHAPE_GLSL
#define FIBERS_SHAPE_GLSL

uniform float uEllipsoid;
uniform float uTwist;           // turns over the guide
uniform int uTwistPattern;
uniform float uCurlAmplitude;   // unit-space radius of the curl
uniform float uCurlFrequency;   // turns over the guide
uniform int uCurlPattern;
uniform float uFrizz;           // shape.frizz: how far each fiber's sway frequency strays from the curl's
uniform float uFrizzAmplitude;  // unit space: the most a fiber's frizz moves it
uniform float uNoiseAmplitude;  // unit space
uniform float uNoiseFrequency;  // turns over the guide

const float TWO_PI = 6.28318530718;

// The uniforms as the functions below read them: copied once per invocation (global initialisers run at
// the top of main). llvmpipe loads a uniform as a gather of eight scalar loads wherever it is read, and the
// compiler keeps the load beside its use, loops included: ~20 instructions per read per pass of the
// traversal's loops. Each copy goes through an ALU operation that leaves the value as it is (abs of a
// value that is never negative, sign times abs for the twist), and an ALU result stays where it is
// computed. Identical values in the same expressions, so identical fibers and colours.
float sEllipsoid = abs(uEllipsoid);
float sTwist = sign(uTwist) * abs(uTwist);      // the signed twist: sign times size is itself
float sTwistAbs = abs(uTwist);
int sTwistPattern = abs(uTwistPattern);
float sCurlAmplitude = abs(uCurlAmplitude);
float sCurlFrequency = abs(uCurlFrequency);
int sCurlPattern = abs(uCurlPattern);
float sFrizz = abs(uFrizz);
float sFrizzAmplitude = abs(uFrizzAmplitude);
float sNoiseAmplitude = abs(uNoiseAmplitude);
float sNoiseFrequency = abs(uNoiseFrequency);

// fallbacks so that the file compiles alone; tests/fibers/test_model.py holds them equal to app.fibers
#ifndef TWIST_UNIFORM
#define TWIST_UNIFORM 0
#define TWIST_RAMPED 1
#define TWIST_ALTERNATING 2
#endif
#ifndef CURL_HELIX
#define CURL_HELIX 0
#define CURL_WAVE 1
#endif

#ifndef CH_FRIZZ_AMP
#define CH_FRIZZ_AMP 7u
#define CH_FRIZZ_FREQ 8u
#define CH_FRIZZ_DIR 9u
#define CH_FRIZZ_PHASE 10u
#define CH_NOISE_PHASE 11u
#endif

#ifndef SHAPE_FRIZZ
#define SHAPE_FRIZZ 1   // 0: built for frizz and noise 0 (the traversal skips their displacement)
#endif

#ifndef SHAPE_TWIST
#define SHAPE_TWIST 1   // 0: built for twist 0 (ring_point skips the rotation)
#endif
#ifndef SHAPE_CURL
#define SHAPE_CURL 3    // what ring_frame_center builds in: 0 no curl, 1 helix, 2 wave, 3 either (by uniform)
#endif
#ifndef SHAPE_ELLIPSOID
#define SHAPE_ELLIPSOID 1   // 0: built for ellipsoid 0 (every scale is 1)
#endif

float shape_twist(float v, int ring) {
    float t = sTwistPattern == TWIST_RAMPED ? v * v : v;
    float sgn = (sTwistPattern == TWIST_ALTERNATING && (ring & 1) == 1) ? -1.0 : 1.0;
    return sgn * TWO_PI * sTwist * t;
}

// v is taken within the guide, [0, 1]: the wedge of a slab past a tilted root or tip cap reaches beyond
// it (Bangs_100.hair to v = 1.39), where the formula would close every ring onto the axis, and every
// bound that takes the segment's smallest scale with it (renderer.py: _shaped_arc_passes).
float shape_scale(float v) {
    float x = sEllipsoid * (2.0 * clamp(v, 0.0, 1.0) - 1.0);
    return sqrt(max(0.0, 1.0 - x * x));
}

// The most a fiber's centre moves off its scaled, twisted rest line: the bands, the reach and the chord
// rule take it (shaped.glsl, curved.glsl). Zeros when frizz and noise are off, so the curl's alone.
float shape_displacement() {
    return sCurlAmplitude + sFrizzAmplitude + sNoiseAmplitude;
}

// Frizz and noise: each fiber sways along its own direction (dir, fixed in the ring's frame, as the wave)
// by amp sin(2 pi (freq v + phase)), freq the curl's times 1 + frizz (u - 1/2), and the noise sways across
// it at uNoiseFrequency with its own phase. The numbers come from the curl phase's bits (app/fibers/hash.py:
// wiggle_key), so whatever holds a fiber's curl phase holds its frizz.
struct Frizz { vec2 dir; float amp; float freq; float phase; float noisePhase; };

Frizz frizz_of(float curlPhase) {
    uint key = uint(curlPhase * 16777216.0);
    float theta = TWO_PI * key_random(key, CH_FRIZZ_DIR);
    Frizz f;
    f.dir = vec2(cos(theta), sin(theta));
    f.amp = sFrizzAmplitude * key_random(key, CH_FRIZZ_AMP);
    f.freq = sCurlFrequency * (1.0 + sFrizz * (key_random(key, CH_FRIZZ_FREQ) - 0.5));
    f.phase = key_random(key, CH_FRIZZ_PHASE);
    f.noisePhase = key_random(key, CH_NOISE_PHASE);
    return f;
}

// The displacement at height v, in the ring's frame.
vec2 frizz_offset(Frizz f, float v) {
    float k = f.amp * sin(TWO_PI * (f.freq * v + f.phase));
    float m = sNoiseAmplitude * sin(TWO_PI * (sNoiseFrequency * v + f.noisePhase));
    return k * f.dir + m * vec2(-f.dir.y, f.dir.x);
}

// The SHAPE_ defines leave out what the parameters do not use (llvmpipe runs both sides of every branch):
// an ellipsoid of 0 scales by sqrt(1) = 1, an unused curl or frizz adds nothing, so the results are the
// same bits either way. (The twist stays: llvmpipe's cos 0 need not be exactly 1, and shading has
// always turned by it.)
vec2 fiber_center_at(vec2 rest, float v, int ring, float curlPhase) {
    float tau = shape_twist(v, ring);
    float ct = cos(tau), st = sin(tau);
    vec2 c = vec2(ct * rest.x - st * rest.y, st * rest.x + ct * rest.y);
#if SHAPE_ELLIPSOID
    c = shape_scale(v) * c;
#endif
#if SHAPE_CURL != 0
    if (sCurlAmplitude > 0.0) {
        float a = TWO_PI * (sCurlFrequency * v + curlPhase);
#if SHAPE_CURL != 2
        if (SHAPE_CURL == 1 || sCurlPattern == CURL_HELIX) {
            c += sCurlAmplitude * vec2(cos(a), sin(a));
        }
#endif
#if SHAPE_CURL != 1
        if (SHAPE_CURL == 2 || sCurlPattern != CURL_HELIX) {
            float len = length(c);
            vec2 along = len > 0.0 ? vec2(-c.y, c.x) / len : vec2(1.0, 0.0);
            c += sCurlAmplitude * sin(a) * along;
        }
#endif
    }
#endif
#if SHAPE_FRIZZ
    if (sFrizzAmplitude > 0.0 || sNoiseAmplitude > 0.0) {
        vec2 f = frizz_offset(frizz_of(curlPhase), v);
        c += vec2(ct * f.x - st * f.y, st * f.x + ct * f.y);
    }
#endif
    return c;
}

// The ray at parameter s as the ring's frame sees it: p = R(-tau) (O.xy + s D.xy), and what the fiber
// centres need at that height (v, E(v), tau and its cosine and sine).
struct RingPoint {
    float s;
    float v;
    float e;
    float tau;
    vec2 cs;        // (cos tau, sin tau)
    vec2 p;
};

RingPoint ring_point(Segment seg, UnitRay ur, float s, int ring) {
    RingPoint P;
    P.s = s;
    P.v = unit_to_v(seg, ur.O.z + s * ur.D.z);
#if SHAPE_ELLIPSOID
    P.e = shape_scale(P.v);
#else
    P.e = 1.0;
#endif
    vec2 q = ur.O.xy + s * ur.D.xy;
#if SHAPE_TWIST
    P.tau = shape_twist(P.v, ring);
    P.cs = vec2(cos(P.tau), sin(P.tau));
    P.p = vec2(P.cs.x * q.x + P.cs.y * q.y, P.cs.x * q.y - P.cs.y * q.x);
#else
    P.tau = 0.0;                // no twist: the ring's frame is the container's
    P.cs = vec2(1.0, 0.0);
    P.p = q;
#endif
    return P;
}

// c'(v) at the height of P. The helix turns at 2 pi F less the twist's rate in this frame; the wave sways
// along the ring, which in this frame is a fixed direction (where the fiber is off the axis).
// Curl turn: the curl's angle at P is (a - tau, a) with a = 2 pi (F v + phase); from one end of a chord
// piece to the other both advance by the same amount for every fiber (ring_curl_step), so a piece's far
// end takes its curl from the near end's by a rotation instead of another sine and cosine.
struct CurlTurn { vec2 h; vec2 w; };    // (cos, sin) of a - tau (helix) and of a (wave)

// (cos, sin) of 2 pi x for x in turns, from one reduction shared by two short polynomials: a curled
// fiber's test takes a pair per candidate, and llvmpipe's cos and sin reduce the angle each on its own
// (2-3.5 % of the bench's curled and combined frames, one process). The reduction in turns is exact
// (x - round(x)); the polynomials (Cephes' sinf and cosf on [-pi/4, pi/4]) are within ~1e-7 of the true
// values (tests/gl/test_glsl_functions.py).
vec2 turn_cos_sin(float x) {
    float r = x - round(x);                 // [-1/2, 1/2] turns
    float q = round(4.0 * r);               // the quarter turn nearest
    float y = (r - 0.25 * q) * TWO_PI;      // [-pi/4, pi/4] radians
    float y2 = y * y;
    float sn = y + y * y2 * (-1.6666654611e-1 + y2 * (8.3321608736e-3 + y2 * -1.9515295891e-4));
    float cs = 1.0 - 0.5 * y2 + y2 * y2 * (4.166664568298827e-2 + y2 * (-1.388731625493765e-3
             + y2 * 2.443315711809948e-5));
    int k = int(q) & 3;                     // turn (cs, sn) by k quarter turns
    vec2 a = (k & 1) == 0 ? vec2(cs, sn) : vec2(-sn, cs);
    return (k & 2) == 0 ? a : -a;
}

CurlTurn curl_turn(float curlPhase, RingPoint P) {
    float a = sCurlFrequency * P.v + curlPhase;         // turns
    CurlTurn c;
    c.h = turn_cos_sin(a - P.tau * (1.0 / TWO_PI));
    c.w = turn_cos_sin(a);
#if SHAPE_CURL == 1
    c.w = vec2(1.0, 0.0);
#elif SHAPE_CURL == 2
    c.h = vec2(1.0, 0.0);
#endif
    return c;
}

// (cos, sin) of how far the helix's and the wave's angles advance from P0 to P1: (helix, wave) as a vec4.
vec4 ring_curl_step(RingPoint P0, RingPoint P1) {
    float dw = TWO_PI * sCurlFrequency * (P1.v - P0.v);
    float dh = dw - (P1.tau - P0.tau);
    return vec4(cos(dh), sin(dh), cos(dw), sin(dw));
}

CurlTurn curl_advance(CurlTurn c, vec4 step) {
    CurlTurn n;
    n.h = vec2(c.h.x * step.x - c.h.y * step.y, c.h.y * step.x + c.h.x * step.y);
    n.w = vec2(c.w.x * step.z - c.w.y * step.w, c.w.y * step.z + c.w.x * step.w);
    return n;
}

vec2 ring_frame_center(vec2 rest, CurlTurn curl, RingPoint P) {
    vec2 c = P.e * rest;
#if SHAPE_CURL != 0
#if SHAPE_CURL != 1
    float r2 = dot(rest, rest);
    vec2 along = r2 > 0.0 && P.e > 0.0 ? vec2(-rest.y, rest.x) * inversesqrt(r2) : vec2(P.cs.x, -P.cs.y);
    vec2 wave = curl.w.y * along;
#endif
#if SHAPE_CURL == 1
    c += sCurlAmplitude * curl.h;
#elif SHAPE_CURL == 2
    c += sCurlAmplitude * wave;
#else
    c += sCurlAmplitude * (sCurlPattern == CURL_HELIX ? curl.h : wave);
#endif
#endif
    return c;
}

#endif
