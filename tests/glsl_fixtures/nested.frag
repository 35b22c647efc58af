#version 450
// nested.frag: a includes b, then b again directly; b must appear once.
#include "lib/a.glsl"
#include "lib/b.glsl"  // already in through a.glsl
out vec4 fragColor;
void main() { fragColor = vec4(lib_a(0.25), lib_b(0.25), 0.0, 1.0); }
