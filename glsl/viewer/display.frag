#version 330 core
// display.frag: show the renderer's outputs in the window's viewport, one debug view per variant
// (#define VIEW, injected by the viewer; a uniform switch costs llvmpipe 5x on every pixel).
// The render may be smaller than the viewport (interactive scale): shaded and heat map are filtered,
// the integer views (ids, rings) and normals/depth are fetched at the nearest texel.
//   VIEW 0 shaded    colour / samples (premultiplied sRGB, coverage in alpha) over the background
//   VIEW 1 fiber ids hash of (guide + 1, ring, fiber) to a colour
//   VIEW 2 rings     ring index on the heat ramp: (ring + 1) / rings, outer ring dark, inner ring hot
//   VIEW 3 normals   world normal * 0.5 + 0.5
//   VIEW 4 depth     ray distance over uDepthRange: near white .. far 15 % grey
//   VIEW 5 heat map  fiber tests per pixel on the heat ramp, 0 .. uHeatMax
// Views 1-5 use app/render/debug_views.py's colours (the CLI's --output pictures); a miss shows the
// background here (the CLI writes black).
//   VIEW 6 proxies   the shaded image faded toward the background (proxy.* draws the wireframes over it)

#ifndef VIEW
#define VIEW 0
#endif

#include "common/epsilon.glsl"
#include "viewer/palette.glsl"

in vec2 vUv;

uniform sampler2D uAccum;       // sum of samples (or the single sample): premultiplied sRGB, coverage
uniform usampler2D uIds;        // guide + 1, ring, fiber, segment
uniform sampler2D uGeom;        // normal xyz, ray distance
uniform sampler2D uCost;        // fiber tests, arcs, container fragments, loop iterations
uniform float uSamples;
uniform vec3 uBackgroundSrgb;   // the background as the renderer composites it (display space)
uniform int uRings;
uniform vec2 uDepthRange;
uniform float uHeatMax;
uniform float uDim;

out vec4 outColor;

void main() {
    vec3 bg = uBackgroundSrgb;
#if VIEW == 0 || VIEW == 6
    vec4 sum = texture(uAccum, vUv) / uSamples;
    vec3 c = sum.rgb + (1.0 - clamp(sum.a, 0.0, 1.0)) * bg;
#if VIEW == 6
    c = mix(bg, c, uDim);                        // faded, so the wireframes read over it
#endif
#elif VIEW == 5
    vec4 cost = texture(uCost, vUv);
    vec3 c = cost.z > 0.0 ? heat_color(cost.x / max(uHeatMax, 1e-6)) : bg * 0.5;
#else
    ivec2 texel = ivec2(vUv * vec2(textureSize(uIds, 0)));
    uvec4 id = texelFetch(uIds, texel, 0);
    vec3 c = bg;
    if (id.x > 0u) {
#if VIEW == 1
        c = id_color(id.xyz);
#elif VIEW == 2
        c = heat_color((float(id.y) + 1.0) / float(max(uRings, 1)));
#elif VIEW == 3
        c = texelFetch(uGeom, texel, 0).xyz * 0.5 + 0.5;
#elif VIEW == 4
        float d = (texelFetch(uGeom, texel, 0).w - uDepthRange.x) / max(uDepthRange.y - uDepthRange.x, EPS_DIVISOR);
        c = as_uint8(vec3(1.0 - 0.85 * clamp(d, 0.0, 1.0)));
#endif
    }
#endif
    outColor = vec4(c, 1.0);
}
