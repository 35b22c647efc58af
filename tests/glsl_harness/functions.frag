#version 450 core
// Evaluates library functions per pixel so tests can hold them against app/reference.py value by value.
#include "common/hash.glsl"
#include "geometry/intervals.glsl"

uniform uint uSeed;
uniform vec4 uRay;          // o.xy, d.xy for circle_interval
uniform float uRadius;
layout(location = 0) out uvec4 outHash;     // lowbias32(x), fiber key, 24-bit random as bits
layout(location = 1) out vec4 outValues;    // fiber_random, thesis_random, circle interval (t0, t1)

void main() {
    uint x = uint(gl_FragCoord.x);
    uint y = uint(gl_FragCoord.y);
    outHash = uvec4(lowbias32(x * 7919u + y), fiber_key(uSeed, x, y, x ^ y), 0u, 0u);
    float slot = float(x) * 0.37 + float(y) * 3.1;
    vec2 o = uRay.xy + vec2(float(x), float(y)) * 0.01;
    vec2 iv = circle_interval(o, uRay.zw, vec2(0.2, -0.1), uRadius);
    outValues = vec4(fiber_random(uSeed, x, y, x + y, 2u), thesis_random(slot, float(y % 7u), 1.0), iv);
}
