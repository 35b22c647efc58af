// b.glsl: the innermost library file of the include tests.
//   float lib_b(float x)
float lib_b(float x) { return 2.0 * x; }
