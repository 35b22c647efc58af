#version 330 core
// compare.frag: the pinned look (A) drawn over the live one (B) left of the split, with a thin line at
// the split. The viewer sets the viewport to the render area and the scissor to A's part of it.
// In: vUv over the render area. uImage: A as the renderer composites it (display-space RGB).

in vec2 vUv;
uniform sampler2D uImage;
uniform float uSplitX;          // split position in the render area's pixels from its left edge
layout(location = 0) out vec4 outColor;

void main() {
    vec3 a = texture(uImage, vUv).rgb;
    float edge = abs(gl_FragCoord.x - uSplitX);
    outColor = vec4(edge < 1.5 ? vec3(1.0, 0.78, 0.35) : a, 1.0);
}
