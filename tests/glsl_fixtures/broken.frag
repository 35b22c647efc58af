#version 450
// broken.frag: pulls the broken library in after a clean one, so the error sits deep in the expansion.
#include "lib/a.glsl"
#include "broken.glsl"
out vec4 fragColor;
void main() { fragColor = vec4(broken_value(lib_a(0.5))); }
