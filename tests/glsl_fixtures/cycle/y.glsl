// y.glsl: the other half of the cycle.

#include "cycle/x.glsl"
