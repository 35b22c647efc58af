// x.glsl: half of a deliberate include cycle.
#include "cycle/y.glsl"
