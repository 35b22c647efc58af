#version 330 core
// proxy.frag: wireframe colour per guide (hashed), so neighbouring containers are told apart.

#include "viewer/palette.glsl"

flat in float vGuide;
uniform float uAlpha;
out vec4 outColor;

void main() {
    outColor = vec4(mix(id_color(uvec3(uint(vGuide) + 1u, 0u, 0u)), vec3(1.0), 0.35), uAlpha);
}
