// candidates.glsl: which fibers of a ring an arc of the ray can hit, as runs of fiber indices.
//   ivec2 ring_share(int i, ivec2 range)       the share of ring i's fibers this draw tests
//   ivec2 candidate_run(int r, int j0, int dir, int count, int n, ivec2 share)
//   int   candidate(ivec2 run0, ivec2 run1, int dir, int t)     the t-th candidate of the two runs
//   float wrap_pi(float a)                     an angle into [-pi, pi)
// Only fibers whose slot angle lies within the arc's angles widened by the ring's reach can be hit; those
// slots are consecutive fiber indices mod n, taken in the order the ray meets them.

#include "fibers/layout.glsl"

#ifndef FIBERS_CANDIDATES_GLSL
#define FIBERS_CANDIDATES_GLSL

float wrap_pi(float a) {
    return a - 6.28318530718 * floor((a + 3.14159265359) / 6.28318530718);
}

// The share [lo, hi) of ring i's fibers this draw tests: the renderer splits the fibers over draws when
// one traversal could otherwise pass llvmpipe's loop budget (renderer.py: draw_ranges); unset, all.
ivec2 ring_share(int i, ivec2 range) {
    ivec2 nf = uRingN[i];
    return range.y <= range.x ? ivec2(0, nf.x) : clamp(range - nf.y, 0, nf.x);
}

// The candidates j0, j0 + dir, ... (count <= n of them, taken mod n) are at most two runs j = base + dir k,
// before and after the wrap past fiber 0; run r clipped to the share: (first j, number of fibers).
ivec2 candidate_run(int r, int j0, int dir, int count, int n, ivec2 share) {
    int m0 = j0 - n * int(floor(float(j0) / float(n)));   // the first candidate, in [0, n)
    int wrapK = dir > 0 ? n - m0 : m0 + 1;                 // k of the first candidate past the wrap
    int base = r == 0 ? m0 : m0 - dir * n;
    int kA = r == 0 ? 0 : wrapK;
    int kB = r == 0 ? min(count, wrapK) : count;
    kA = max(kA, dir > 0 ? share.x - base : base - share.y + 1);
    kB = min(kB, dir > 0 ? share.y - base : base - share.x + 1);
    return ivec2(base + dir * kA, max(0, kB - kA));
}

// The t-th candidate of the two runs: one loop over both, so that lanes of one SIMD batch whose runs
// split differently still cost the batch only the longest lane (llvmpipe's loop budget is per batch).
int candidate(ivec2 run0, ivec2 run1, int dir, int t) {
    ivec2 run = t < run0.y ? ivec2(run0.x, t) : ivec2(run1.x, t - run0.y);
    return dir > 0 ? run.x + run.y : run.x - run.y;     // dir is +-1: no vector multiply (llvmpipe's is slow)
}

#endif
