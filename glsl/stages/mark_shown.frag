#version 450 core
// mark_shown.frag: after the walk, window depth uDepth (past the resolve's) where a pixel the walk ran on
// shows nothing (no hit, and in the filtered mode no colour either), so the resolve's early depth test
// skips it: llvmpipe runs all of a fragment shader for a pixel that discards, and on a groom the coverage
// pass leaves about as many such pixels as hit ones (harolongo: 47,000 of 87,000). The depth test here is
// late on purpose: a fragment that discards must write nothing.

#ifndef FILTER
#define FILTER 0
#endif

layout(binding = 0, rgba32ui) uniform readonly uimage2D uState;
#if FILTER
layout(binding = 5, rgba32f) uniform readonly image2D uAccum;
#endif

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    bool shown = imageLoad(uState, px).x != 0u;        // resolve.frag: the best hit's t (0: none)
#if FILTER
    shown = shown || imageLoad(uAccum, px).a > 0.0;
#endif
    if (shown) discard;
}
