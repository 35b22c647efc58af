#version 330 core
// display.frag: show the renderer's outputs in the window's viewport, one debug view at a time.
// The render may be smaller than the viewport (interactive scale): shaded and heat map are filtered,
// the integer views (ids, rings) and normals/depth are fetched at the nearest texel.
//   VIEW 0 shaded    accumulated colour / samples, background where coverage < 1
//   VIEW 1 fiber ids hash of (guide + 1, ring, fiber) to a colour
//   VIEW 2 rings     ring index on the heat scale: outer ring 0 yellow -> inner ring K-1 purple
//   VIEW 3 normals   world normal * 0.5 + 0.5
//   VIEW 4 depth     ray distance, near (white) to far (black) over uDepthRange
//   VIEW 5 heat map  fiber tests per pixel on the heat scale, 0 .. uHeatMax
//   VIEW 6 proxies   the shaded image faded toward the background (proxy.* draws the wireframes over it)

#include "viewer/palette.glsl"

in vec2 vUv;

uniform int uView;
uniform sampler2D uAccum;       // RGBA32F sum of samples (sRGB colour, coverage)
uniform usampler2D uIds;        // guide + 1, ring, fiber, segment
uniform sampler2D uGeom;        // normal xyz, ray distance
uniform sampler2D uCost;        // fiber tests, arcs, container fragments, loop iterations
uniform float uSamples;
uniform vec3 uBackground;       // linear RGB
uniform int uRings;
uniform vec2 uDepthRange;
uniform float uHeatMax;
uniform float uDim;

out vec4 outColor;

vec3 shaded() {
    vec4 sum = texture(uAccum, vUv) / max(uSamples, 1.0);
    return sum.rgb + (1.0 - clamp(sum.a, 0.0, 1.0)) * background_srgb(uBackground);
}

void main() {
    vec3 bg = background_srgb(uBackground);
    vec3 c = bg;
    if (uView == 0 || uView == 6) {
        c = shaded();
        if (uView == 6) c = mix(bg, c, uDim);   // faded, so the wireframes read over it
    } else if (uView == 5) {
        vec4 cost = texture(uCost, vUv);
        c = cost.z > 0.0 ? heat_color(cost.x / max(uHeatMax, 1e-6)) : bg * 0.5;
    } else {
        ivec2 texel = ivec2(vUv * vec2(textureSize(uIds, 0)));
        uvec4 id = texelFetch(uIds, texel, 0);
        vec4 geom = texelFetch(uGeom, texel, 0);
        if (id.x > 0u) {
            if (uView == 1) {
                c = id_color(id.xyz);
            } else if (uView == 2) {
                float r = float(id.y) / float(max(uRings - 1, 1));
                c = heat_color(1.0 - r) * ((id.y & 1u) == 0u ? 1.0 : 0.75);   // neighbours told apart
            } else if (uView == 3) {
                c = normalize(geom.xyz) * 0.5 + 0.5;
            } else if (uView == 4) {
                float d = (geom.w - uDepthRange.x) / max(uDepthRange.y - uDepthRange.x, 1e-30);
                c = vec3(1.0 - clamp(d, 0.0, 1.0));
            }
        }
    }
    outColor = vec4(c, 1.0);
}
