#version 450
// color.frag: RED is a #define variant; lib_b(0.25) = 0.5 proves includes reach the driver.
#include "lib/a.glsl"
#ifndef RED
#define RED 0
#endif
out vec4 fragColor;
void main() { fragColor = vec4(float(RED), lib_b(0.25), 0.0, 1.0); }
