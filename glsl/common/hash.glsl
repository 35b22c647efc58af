// hash.glsl: per-fiber random numbers.
//   uint  lowbias32(uint x)                        Chris Wellons' integer hash
//   float fiber_random(uint seed, uint guide, uint ring, uint fiber, uint channel)   in [0, 1), 24 bits
//   uint fiber_key(seed, guide, ring, fiber); float key_random(uint key, uint channel)   the same, factored
//   uint ring_key(seed, guide, ring)      the part of fiber_key shared by one ring's fibers
//   vec3 key_randoms(uint key)            a fiber's radial, angular and length numbers
//   float thesis_random(float slotDeg, float ring, float channel)   fract(1207.523 * phi), thesis 3.4
// fiber_random depends only on integers, so a fiber's numbers never change with the camera or with
// float rounding; thesis_random is kept for fidelity to the thesis and measured against it.
// Twin: app/fibers/hash.py (every function, same names); OSL: osl/common/hash.osl (vf_NAME).
#ifndef COMMON_HASH_GLSL
#define COMMON_HASH_GLSL

// The channels are app/fibers/hash.py's CHANNELS, injected as defines (app.fibers.glsl_defines). These
// fallbacks only let the file compile alone (a test harness); tests/fibers/test_model.py holds them equal.
#ifndef CH_RADIAL
#define CH_RADIAL 0u
#define CH_ANGULAR 1u
#define CH_LENGTH 2u
#define CH_TINT 3u
#define CH_ROUGH 4u
#define CH_CURL 5u
#define CH_RING 6u
#endif

uint lowbias32(uint x) {
    x ^= x >> 16;
    x *= 0x7feb352du;
    x ^= x >> 15;
    x *= 0x846ca68bu;
    x ^= x >> 16;
    return x;
}

// The hash of (seed, guide, ring, fiber) in two parts: the ring's, shared by its fibers, then the fiber's.
// Each channel costs one more round.
uint ring_key(uint seed, uint guide, int ring) {
    uint h = lowbias32(seed + 0x9e3779b9u);
    h = lowbias32(h ^ guide);
    return lowbias32(h ^ uint(ring));
}

uint fiber_key(uint seed, uint guide, uint ring, uint fiber) {
    return lowbias32(ring_key(seed, guide, int(ring)) ^ fiber);
}

float key_random(uint key, uint channel) {
    return float(lowbias32(key ^ channel) >> 8) * (1.0 / 16777216.0);
}

// The three numbers that place a fiber: radial, angular, length.
vec3 key_randoms(uint key) {
    return vec3(key_random(key, CH_RADIAL), key_random(key, CH_ANGULAR), key_random(key, CH_LENGTH));
}

float fiber_random(uint seed, uint guide, uint ring, uint fiber, uint channel) {
    return key_random(fiber_key(seed, guide, ring, fiber), channel);
}

float thesis_random(float slotDeg, float ring, float channel) {
    return fract(1207.523 * (slotDeg + 0.37 * channel + 0.11 * ring));
}

#endif  // COMMON_HASH_GLSL
