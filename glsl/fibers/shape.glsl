// shape.glsl: fibers that are not straight pins (thesis 3.10, Figures 26-34).
//   vec2  fiber_center_at(vec2 rest, float v, int ring, float curlPhase)   unit-space centre at height v
//   float shape_twist(float v, int ring)     rotation of the pattern about the axis, radians
//   float shape_scale(float v)               ellipsoid: radial scale of every ring at height v
//   vec2  twist_range(float va, float vb, int ring)   (min, max) rotation over a stretch of height
// v is the guide parameter (0 root .. 1 tip). A fiber's centre at height v is its rest position scaled by
// the ellipsoid, rotated by the twist, plus the curl offset:
//   c(v) = E(v) R(tau(v)) rest + curl(v)
// Ellipsoid: rings follow x^2 + y^2 = r^2 (1 - e^2 (2v - 1)^2): e = 0 is the cylinder (a degenerate
// ellipsoid), e = 1 the ellipsoid inscribed in the guide's length.
// Twist patterns: 0 uniform tau = 2 pi T v, 1 ramped tau = 2 pi T v^2, 2 alternating: the sign flips
// ring by ring. Curl patterns: 0 helix (a circle about the rest line), 1 wave (a sway along the ring).
// Twin: app/reference.py (fiber_center_at, shape_twist, shape_scale).

uniform float uEllipsoid;
uniform float uTwist;           // turns over the guide
uniform int uTwistPattern;
uniform float uCurlAmplitude;   // unit-space radius of the curl
uniform float uCurlFrequency;   // turns over the guide
uniform int uCurlPattern;

const float TWO_PI = 6.28318530718;

float shape_twist(float v, int ring) {
    float t = uTwistPattern == 1 ? v * v : v;
    float sgn = (uTwistPattern == 2 && (ring & 1) == 1) ? -1.0 : 1.0;
    return sgn * TWO_PI * uTwist * t;
}

vec2 twist_range(float va, float vb, int ring) {
    float a = shape_twist(va, ring);
    float b = shape_twist(vb, ring);
    return vec2(min(a, b), max(a, b));   // monotonic in v for every pattern (v >= 0)
}

float shape_scale(float v) {
    float x = uEllipsoid * (2.0 * v - 1.0);
    return sqrt(max(0.0, 1.0 - x * x));
}

vec2 fiber_center_at(vec2 rest, float v, int ring, float curlPhase) {
    float tau = shape_twist(v, ring);
    float ct = cos(tau), st = sin(tau);
    vec2 c = shape_scale(v) * vec2(ct * rest.x - st * rest.y, st * rest.x + ct * rest.y);
    if (uCurlAmplitude > 0.0) {
        float a = TWO_PI * (uCurlFrequency * v + curlPhase);
        if (uCurlPattern == 0) {
            c += uCurlAmplitude * vec2(cos(a), sin(a));
        } else {
            float len = length(c);
            vec2 along = len > 0.0 ? vec2(-c.y, c.x) / len : vec2(1.0, 0.0);
            c += uCurlAmplitude * sin(a) * along;
        }
    }
    return c;
}
