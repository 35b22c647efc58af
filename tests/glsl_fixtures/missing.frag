#version 450
// missing.frag: line 4 includes a file that does not exist.

#include "lib/nope.glsl"
void main() {}
