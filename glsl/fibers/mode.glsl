// mode.glsl: which traversal mode runs and which share of the fibers this draw tests.
// TRAVERSAL selects the mode (traverse.glsl's header says what each does): 0 fast, 1 exact, 2 brute. A
// shadow ray switches gMode to 0 for itself and skips the fiber it starts on (gSkipRing, gSkipFiber).
// The renderer splits a container's fibers over draws to stay under llvmpipe's loop budget
// (renderer.py: draw_ranges): uFiberRange (fast, exact) and uBruteRange (brute) are this draw's share of
// the container's flat fiber numbering; uRingOrder makes the traversal loops go by ring index.

#ifndef FIBERS_MODE_GLSL
#define FIBERS_MODE_GLSL

#ifndef TRAVERSAL
#define TRAVERSAL 1
#endif

int gMode = TRAVERSAL;          // a shadow ray switches to 0 (any hit) for itself
int gSkipRing = -1;             // a shadow ray starts on this fiber: never count it as a blocker
int gSkipFiber = -1;
uniform ivec2 uBruteRange;
uniform ivec2 uFiberRange;      // fast, exact: test only fibers [x, y) of the container's flat numbering
uniform int uRingOrder;         // 1: the loops after the ring loop go by ring index (renderer.py: draw_ranges)

#endif
