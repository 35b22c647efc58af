// hit.glsl: the best hit of a traversal so far, and the order that decides between two hits.
//   FiberHit no_hit()
//   bool beats(float s, int ring, int j, float bestS, int bestRing, int bestFiber)
//   bool improves(FiberHit best, float s, int ring, int j)
// Every mode (fast, exact, brute; straight or shaped fibers) keeps its best hit here and breaks ties the
// same way, so all of them name the same fiber.

#include "common/epsilon.glsl"

#ifndef FIBERS_HIT_GLSL
#define FIBERS_HIT_GLSL

struct FiberHit {
    float s;        // unit-space parameter, INF on a miss
    int ring;
    int fiber;
    int kind;       // 0 fiber side, 1 fiber tip (length cut), 2 container boundary (cap or joint),
                    // 3 the side of a tapered fiber's cone (taper.glsl)
    vec2 c;         // fiber centre in unit space
    vec2 dcdv;      // how the centre moves with the guide parameter (curved fibers; 0 when straight)
};

FiberHit no_hit() {
    FiberHit h;
    h.s = INF;
    h.ring = -1;
    h.fiber = -1;
    h.kind = 0;
    h.c = vec2(0.0);
    h.dcdv = vec2(0.0);
    return h;
}

// Whether a hit at s on fiber (ring, j) replaces the best so far. Ties (a ray entering through a cap
// inside two overlapping fibers) go to the lower (ring, fiber), the order brute force tests them in, so
// every mode names the same fiber.
bool beats(float s, int ring, int j, float bestS, int bestRing, int bestFiber) {
    bool tie = s == bestS && (ring < bestRing || (ring == bestRing && j < bestFiber));
    return s < bestS || (tie && s < INF);
}

bool improves(FiberHit best, float s, int ring, int j) {
    return beats(s, ring, j, best.s, best.ring, best.fiber);
}

#endif
