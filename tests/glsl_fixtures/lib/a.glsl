// a.glsl: includes b.glsl, so stage files that include both see b once.
//   float lib_a(float x)
#include "lib/b.glsl"
float lib_a(float x) { return lib_b(x) + 1.0; }
