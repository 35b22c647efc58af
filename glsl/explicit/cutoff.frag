#version 450 core
// cutoff.frag: quality.filter = coverage on the explicit baseline (app/render/explicit.py: _filtered_color).
// After the optical-depth bins of a pixel are summed (ribbon.frag FILTER 2), the pixel is opaque behind the
// end of the first bin whose light through it and all before it falls under CUTOFF_TRANSMITTANCE; this
// writes that distance as the pixel's window depth, so the colour pass (FILTER 3) meets the early depth
// test there and never shades the fragments that could add less than that. llvmpipe skips nothing for a
// discard or a branch (docs/performance.md); a depth test before the shader is the only cut. A pixel that
// never turns opaque within the bins keeps the far plane: every fragment passes.

layout(location = 0) out vec4 outNothing;   // the colour mask is off: depth only

uniform sampler2D uNearest;
uniform sampler2D uBins0;
uniform sampler2D uBins1;
uniform sampler2D uBins2;
uniform sampler2D uBins3;
uniform float uBinWidth;
uniform mat4 uClipFromCamera;   // the ribbons' projection (ribbon.vert), the sub-pixel offset included
uniform mat4 uCameraFromClip;   // its inverse
uniform vec2 uSize;             // the viewport in pixels

#define BINS 16
#define CUTOFF_TAU 6.93         // -log(1 / 1024): what lies behind adds under a thousandth of the pixel

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec4 b[4] = vec4[4](texelFetch(uBins0, px, 0), texelFetch(uBins1, px, 0), texelFetch(uBins2, px, 0),
                        texelFetch(uBins3, px, 0));
    float tau = 0.0;
    int opaque = BINS;          // the first bin at whose end the pixel is opaque (BINS: none)
    for (int i = 0; i < BINS - 1; i++) {
        tau += b[i >> 2][i & 3];
        opaque = opaque == BINS && tau > CUTOFF_TAU ? i : opaque;
    }
    float dist = texelFetch(uNearest, px, 0).x + float(opaque + 1) * uBinWidth;
    vec2 ndc = gl_FragCoord.xy / uSize * 2.0 - 1.0;
    vec4 far = uCameraFromClip * vec4(ndc, 1.0, 1.0);
    vec3 dir = normalize(far.xyz / far.w);
    vec4 clip = uClipFromCamera * vec4(dir * dist, 1.0);
    float depth = clamp(0.5 + 0.5 * clip.z / clip.w, 0.0, 1.0);
    gl_FragDepth = opaque < BINS ? depth : 1.0;
    outNothing = vec4(0.0);
}
