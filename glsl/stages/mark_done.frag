#version 450 core
// mark_done.frag: after a walk draw, write depth (the fullscreen pass's) where the pixel's walk is
// done, so the early depth test keeps it out of the next walk draw. The test here is late on purpose:
// with early tests a fragment writes depth before the shader runs and a discard cannot take it back.

layout(binding = 0, rgba32ui) uniform readonly uimage2D uState;

void main() {
    if (imageLoad(uState, ivec2(gl_FragCoord.xy)).z != 0xFFFFFFFFu) discard;     // bvh.glsl: WALK_DONE
}
