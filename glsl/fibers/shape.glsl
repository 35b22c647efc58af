// shape.glsl: fibers that are not straight pins (thesis 3.10, Figures 26-34).
//   vec2  fiber_center_at(vec2 rest, float v, int ring, float curlPhase)   unit-space centre at height v
//   float shape_twist(float v, int ring)     rotation of the pattern about the axis, radians
//   float shape_scale(float v)               ellipsoid: radial scale of every ring at height v
//   RingPoint ring_point(Segment seg, UnitRay ur, float s, int ring)   the ray at s and ring's shape there
//   vec2  piece_center(vec2 turned, vec2 curl, RingPoint P)   a fiber's centre at P, from its turned rest
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
// in it. The traversal chooses its candidates in that frame (shaped.glsl) and tests them in the
// container's, where the ray is straight (curved.glsl: piece_entry).
// Twin: app/fibers/shape.py (fiber_center_at, shape_twist, shape_scale, frizz_randoms, frizz_offset,
// Shape.displacement), app/reference.py (ring_point,
// piece_center). The pattern codes are app/fibers/shape.py's, injected (app.fibers.glsl_defines).

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

// The ray at parameter s, p = O.xy + s D.xy in the container's frame, and what ring's fibers are at that
// height: v, the ellipsoid's E(v) and the ring's twist tau (with its cosine and sine where the frizz turns
// with it; the chord pieces take the twist between their ends in one sine and cosine instead).
struct RingPoint {
    float s;
    float v;
    float e;
    float tau;
    vec2 cs;        // (cos tau, sin tau): SHAPE_FRIZZ only, else (1, 0)
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
    P.p = ur.O.xy + s * ur.D.xy;
#if SHAPE_TWIST
    P.tau = shape_twist(P.v, ring);
#else
    P.tau = 0.0;
#endif
#if SHAPE_TWIST && SHAPE_FRIZZ
    P.cs = vec2(cos(P.tau), sin(P.tau));
#else
    P.cs = vec2(1.0, 0.0);
#endif
    return P;
}

// The curl's angle at P is a = 2 pi (F v + phase) for the helix and the wave alike (the container's
// frame); from one end of a chord piece to the other it advances by the same amount for every fiber
// (ring_curl_step), so a piece's far end takes its curl from the near end's by a rotation instead of
// another sine and cosine.

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

// (cos, sin) of the curl's angle a at P.
vec2 curl_turn(float curlPhase, RingPoint P) {
    return turn_cos_sin(sCurlFrequency * P.v + curlPhase);     // in turns
}

// (cos, sin) of how far the curl's angle advances from P0 to P1.
vec2 ring_curl_step(RingPoint P0, RingPoint P1) {
    float dw = TWO_PI * sCurlFrequency * (P1.v - P0.v);
    return vec2(cos(dw), sin(dw));
}

vec2 curl_advance(vec2 c, vec2 step) {
    return vec2(c.x * step.x - c.y * step.y, c.y * step.x + c.x * step.y);
}

// fiber_center_at at the height of P, in the container's frame, with the fiber's rest position already
// turned by the ring's twist there (turned = R(tau) rest) and the curl's (cos, sin) there. The wave sways
// along the ring: across the turned rest direction (where the fiber is off the axis); the frizz is
// piece_entry's.
vec2 piece_center(vec2 turned, vec2 curl, RingPoint P) {
    vec2 c = P.e * turned;
#if SHAPE_CURL != 0
#if SHAPE_CURL != 1
    float r2 = dot(turned, turned);
    vec2 along = r2 > 0.0 && P.e > 0.0 ? vec2(-turned.y, turned.x) * inversesqrt(r2) : vec2(1.0, 0.0);
    vec2 wave = curl.y * along;
#endif
#if SHAPE_CURL == 1
    c += sCurlAmplitude * curl;
#elif SHAPE_CURL == 2
    c += sCurlAmplitude * wave;
#else
    c += sCurlAmplitude * (sCurlPattern == CURL_HELIX ? curl : wave);
#endif
#endif
    return c;
}

#endif
