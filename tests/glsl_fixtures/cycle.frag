#version 450
#include "cycle/x.glsl"
void main() {}
