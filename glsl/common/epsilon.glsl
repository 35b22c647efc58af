// epsilon.glsl: every tolerance of the ray caster, in one place.
// Angles are radians, lengths are in unit space (container radius = 1).

// Slack added to a fiber's angular reach so float32 rounding of atan() never drops a candidate.

#ifndef COMMON_EPSILON_GLSL
#define COMMON_EPSILON_GLSL

const float EPS_ANGLE = 2e-5;
// Relative slack of the bounding cylinder used before entering unit space.
const float EPS_BOUND = 1e-4;
const float INF = 1e38;  // larger than any distance; finite so it is a legal constant

#endif
