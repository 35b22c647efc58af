// layout.glsl: where virtual fibers sit inside a container (thesis 3.3-3.8, 4.3).
//   void fiber_center(uint guide, int ring, int j, out vec2 c, out float vEnd)
// Ring i (0 = outermost) is the annulus [1 - (i+1)/K, 1 - i/K] of unit space. Its n_i fibers sit at angles
// rot_i + j dphi_i, pushed by a radial and an angular offset that are bounded per ring so that a fiber
// never leaves its slot; vEnd is where along the guide (0 root .. 1 tip) the fiber stops.
// The per-ring numbers are computed once on the CPU (app/reference.py: ring_layout) and arrive here.
// Twin: app/reference.py (fiber_center).

#include "common/hash.glsl"

#ifndef MAX_RINGS
#define MAX_RINGS 64
#endif
#ifndef HASH_THESIS
#define HASH_THESIS 0
#endif

uniform int uRings;
uniform vec4 uRingA[MAX_RINGS];    // rho, dphi, rot, reach (largest angular offset + disc half-angle)
uniform vec4 uRingB[MAX_RINGS];    // maxDr, maxDphi, -, -
uniform ivec2 uRingN[MAX_RINGS];   // fibers on the ring, index of its first fiber in the container
uniform float uFiberRadius;
uniform float uLengthJitter;
uniform uint uSeed;

// fiber_key(seed, guide, ring, j) = lowbias32(ring_key(seed, guide, ring) ^ j): the ring part is the same
// for every fiber a traversal visits on one ring, so it is kept and reused (same values, 3 rounds fewer).
uint gKeyGuide = 0xffffffffu;
int gKeyRing = -1;
uint gRingKey;

uint cached_fiber_key(uint guide, int ring, int j) {
    if (ring != gKeyRing || guide != gKeyGuide) {
        uint h = lowbias32(uSeed + 0x9e3779b9u);
        h = lowbias32(h ^ guide);
        gRingKey = lowbias32(h ^ uint(ring));
        gKeyRing = ring;
        gKeyGuide = guide;
    }
    return lowbias32(gRingKey ^ uint(j));
}

// The three random numbers that place a fiber: radial, angular, length.
vec3 fiber_placement_randoms(uint guide, int ring, int j) {
#if HASH_THESIS
    float slotDeg = degrees(uRingA[ring].z + float(j) * uRingA[ring].y);
    return vec3(thesis_random(slotDeg, float(ring), float(CH_RADIAL)),
                thesis_random(slotDeg, float(ring), float(CH_ANGULAR)),
                thesis_random(slotDeg, float(ring), float(CH_LENGTH)));
#else
    uint key = cached_fiber_key(guide, ring, j);
    return vec3(key_random(key, CH_RADIAL), key_random(key, CH_ANGULAR), key_random(key, CH_LENGTH));
#endif
}

float fiber_curl_phase(uint guide, int ring, int j) {
#if HASH_THESIS
    float slotDeg = degrees(uRingA[ring].z + float(j) * uRingA[ring].y);
    return thesis_random(slotDeg, float(ring), float(CH_CURL));
#else
    return key_random(cached_fiber_key(guide, ring, j), CH_CURL);
#endif
}

void fiber_center(uint guide, int ring, int j, out vec2 c, out float vEnd) {
    vec4 A = uRingA[ring];
    vec4 B = uRingB[ring];
    vec3 u = fiber_placement_randoms(guide, ring, j);
    float radius = A.x + (2.0 * u.x - 1.0) * B.x;
    float angle = A.z + float(j) * A.y + (2.0 * u.y - 1.0) * B.y;
    c = radius * vec2(cos(angle), sin(angle));
    vEnd = 1.0 - uLengthJitter * u.z;
}
