// counters.glsl: the work a traversal does, for the cost pass (renderer.py: cost outputs).
//   void loop_canary()      after the traversal: raises gIters to LOOP_CAP if llvmpipe cut a loop short
// Counters: gTests (fiber tests), gPieces (arcs visited), gIters (loop iterations, all loops). Every
// traversal loop adds to them; only the cost pass writes them out (stages/*.frag: COST_PASS).

#include "fibers/layout.glsl"

#ifndef FIBERS_COUNTERS_GLSL
#define FIBERS_COUNTERS_GLSL

int gTests = 0;
int gPieces = 0;
int gIters = 0;

// llvmpipe ends every loop of an invocation silently once the invocation has run 65,535 loop iterations
// in all (each pass through a loop header counts, a loop's final test included). The renderer splits the
// fibers over draws so that should never happen (renderer.py: draw_ranges); should it happen anyway, a
// loop of two passes, a length the compiler cannot know, run after the traversal, stops after one, and
// gIters is raised to LOOP_CAP so that the iters and cost outputs say so instead of a fiber going missing
// in silence. Only the cost pass, whose outputs report it, pays for the canary: its loop runs both passes in
// every lane.
const int LOOP_CAP = 65535;

void loop_canary() {
    int trips = 0;
    for (int k = 0; k < 2 + min(uRings, 0); k++) trips++;
    if (trips < 2) gIters = max(gIters, LOOP_CAP);
}

#endif
