// layout.glsl: where virtual fibers sit inside a container (thesis 3.3-3.8, 4.3).
//   void fiber_center(uint guide, int ring, int j, out vec2 c, out float vEnd)
//   float fiber_v_end(vec4 A, uint ringKey, int ring, int j, float lengthJitter)   where it stops
// Ring i (0 = outermost) is the annulus [1 - (i+1)/K, 1 - i/K] of unit space. Its n_i fibers sit at angles
// rot_i + j dphi_i, pushed by a radial and an angular offset that are bounded per ring so that a fiber
// never leaves its slot; vEnd is where along the guide (0 root .. 1 tip) the fiber stops.
// The per-ring numbers are computed once on the CPU (app/fibers/layout.py: ring_layout, in float64) and
// arrive as uniforms (app/render/renderer.py: ring_uniforms).
// Twin: app/fibers/layout.py (fiber_center); OSL: osl/fibers/layout.osl.
#include "common/hash.glsl"

#ifndef FIBERS_LAYOUT_GLSL
#define FIBERS_LAYOUT_GLSL

// MAX_RINGS is app/fibers/limits.py's, injected (app.fibers.glsl_defines); the fallback lets the file
// compile alone, and tests/fibers/test_model.py holds it equal.
#ifndef MAX_RINGS
#define MAX_RINGS 64
#endif
#ifndef HASH_THESIS
#define HASH_THESIS 0
#endif

uniform int uRings;
uniform vec4 uRingA[MAX_RINGS];    // rho, dphi, rot, reach (largest angular offset + disc half-angle)
uniform vec4 uRingB[MAX_RINGS];    // maxDr, maxDphi, 1 / dphi, candidates past a hit (renderer.py: ring_uniforms)
uniform ivec2 uRingN[MAX_RINGS];   // fibers on the ring, index of its first fiber in the container
uniform float uFiberRadius;      // the core's fiber radius, the largest: what bounds the windows
uniform float uRingRadius[MAX_RINGS];   // each ring's (the clump profile thins the outer rings' fibers)
uniform float uLengthJitter;
uniform uint uSeed;

// The three random numbers that place fiber j of a ring: radial, angular, length. A = uRingA[ring];
// ringKey = ring_key(uSeed, guide, ring) (hash.glsl), which a traversal computes once per arc, so each
// fiber costs one hash round more: fiber_key(seed, guide, ring, j) = lowbias32(ringKey ^ j).
vec3 placement_randoms(vec4 A, uint ringKey, int ring, int j) {
#if HASH_THESIS
    float slotDeg = degrees(A.z + float(j) * A.y);
    return vec3(thesis_random(slotDeg, float(ring), float(CH_RADIAL)),
                thesis_random(slotDeg, float(ring), float(CH_ANGULAR)),
                thesis_random(slotDeg, float(ring), float(CH_LENGTH)));
#else
    return key_randoms(lowbias32(ringKey ^ uint(j)));
#endif
}

float fiber_curl_phase(uint guide, int ring, int j) {
#if HASH_THESIS
    float slotDeg = degrees(uRingA[ring].z + float(j) * uRingA[ring].y);
    return thesis_random(slotDeg, float(ring), float(CH_CURL));
#else
    return key_random(fiber_key(uSeed, guide, uint(ring), uint(j)), CH_CURL);
#endif
}

// Where fiber j of a ring stops along the guide (0 root .. 1 tip): its length random scaled by the length
// jitter, uLengthJitter (the shaped traversal passes a copy it read once: shape.glsl says why).
float fiber_v_end(vec4 A, uint ringKey, int ring, int j, float lengthJitter) {
    return 1.0 - lengthJitter * placement_randoms(A, ringKey, ring, j).z;
}

// Fiber j's rest centre turned by `turn` radians about the axis, for a traversal that holds the ring's
// uniforms A = uRingA[ring], B = uRingB[ring] and its ring key already (the shaped traversal turns it by
// the ring's twist in the one cosine and sine the placement takes anyway).
vec2 fiber_rest_turned(vec4 A, vec4 B, uint ringKey, int ring, int j, float turn) {
    vec3 u = placement_randoms(A, ringKey, ring, j);
    float radius = A.x + (2.0 * u.x - 1.0) * B.x;
    float angle = A.z + float(j) * A.y + (2.0 * u.y - 1.0) * B.y + turn;
    return radius * vec2(cos(angle), sin(angle));
}

// Where fiber j of a ring sits (centre c) and where it stops (vEnd).
void fiber_center_keyed(vec4 A, vec4 B, uint ringKey, int ring, int j, out vec2 c, out float vEnd) {
    c = fiber_rest_turned(A, B, ringKey, ring, j, 0.0);
    vEnd = fiber_v_end(A, ringKey, ring, j, uLengthJitter);
}

// The same from the guide and ring alone.
void fiber_center(uint guide, int ring, int j, out vec2 c, out float vEnd) {
    fiber_center_keyed(uRingA[ring], uRingB[ring], ring_key(uSeed, guide, ring), ring, j, c, vEnd);
}

#endif  // FIBERS_LAYOUT_GLSL
