// ring_of.glsl: which ring a fiber belongs to, from its index in the container's flat fiber numbering.
//   int ring_of(int fiber)          binary search of uRingFirst (each ring's first fiber), O(log rings)
// The numbering is the one of app/fibers/layout.py (RingLayout.first): ring 0 (outermost) first.

#ifndef EXPLICIT_RING_OF_GLSL
#define EXPLICIT_RING_OF_GLSL

#ifndef MAX_RINGS
#define MAX_RINGS 64
#endif

uniform int uRings;
uniform int uRingFirst[MAX_RINGS];

int ring_of(int fiber) {
    int lo = 0;
    int hi = uRings - 1;
    while (lo < hi) {
        int mid = (lo + hi + 1) >> 1;
        if (uRingFirst[mid] <= fiber) lo = mid; else hi = mid - 1;
    }
    return lo;
}

#endif
