#version 330 core
// accumulate.frag: add one supersample (the renderer's colour target: sRGB, alpha = coverage) into a
// float accumulation target with additive blending; display.frag divides by the sample count.

uniform sampler2D uColor;
layout(location = 0) out vec4 outAccum;

void main() {
    outAccum = texelFetch(uColor, ivec2(gl_FragCoord.xy), 0);
}
