#version 450 core
// container.vert: rasterize each container segment as its proxy: the rectangle, in the image, that holds
// the projection of an octagonal prism around the segment (its joint planes included), with one side
// along the projected axis. The octagon hugs the circle 8% wider where a square box reaches 41% wider
// seen along a diagonal: 22% fewer fragments and 8% less time at the default scene on llvmpipe. The fragment
// shader does the rest and writes its own depth, so the proxy only decides which pixels run it; a screen
// rectangle (two triangles) covers a thin container with fewer fragments and fewer 4x4 raster blocks cut
// by triangle edges than the box's three visible faces did (llvmpipe shades a block once per triangle).
// A box with a corner at or behind the camera plane projects to no bounded rectangle: that segment covers
// the whole viewport instead (the camera is inside or beside it).
// Positions are camera-relative: scene-relative float32 plus a float64-computed camera offset.

in vec2 in_quad;            // rectangle corner in {0, 1}^2
in vec4 in_a;               // p0.xyz, r0
in vec4 in_b;               // p1.xyz, r1
in vec4 in_c;               // n0.xyz, v0
in vec4 in_d;               // n1.xyz, v1
in vec4 in_e;               // frame x, guide
in int in_segment;          // the segment's index in the scene (the renderer draws them nearest first)

uniform vec3 uSceneFromCamera;  // scene origin minus camera position
uniform mat4 uClipFromCamera;   // projection * view rotation (camera at the origin)
uniform vec2 uViewport;

flat out vec4 vSeg[7];      // the segment, packed (container.glsl: pack_segment)
flat out int vSegment;

#include "geometry/container.glsl"

void main() {
    Segment seg = make_segment(vec4(in_a.xyz + uSceneFromCamera, in_a.w), vec4(in_b.xyz + uSceneFromCamera, in_b.w),
                               in_c, in_d, in_e);
    pack_segment(seg, vSeg);
    vSegment = in_segment;
    float r = seg.rBound * (1.0 + 4.0 * EPS_BOUND);
    vec2 halfViewport = 0.5 * uViewport;
    vec2 corners[16];           // the octagonal prism's corners, in pixels from the viewport centre
    bool behind = false;
    float ro = r * 1.0823922;   // the octagon around the circle: r / cos(22.5 deg)
    for (int k = 0; k < 16; k++) {
        float a = 0.78539816 * float(k & 7);
        vec3 c = vec3(ro * cos(a), ro * sin(a), k < 8 ? seg.zLo : seg.zHi);
        vec4 clip = uClipFromCamera * vec4(seg.p0 + seg.ex * c.x + seg.ey * c.y + seg.ez * c.z, 1.0);
        behind = behind || !(clip.w > EPS_CLIP_W * length(clip.xyz));
        corners[k] = clip.xy / clip.w * halfViewport;
    }
    if (behind) {
        gl_Position = vec4(in_quad * 2.0 - 1.0, 0.0, 1.0);
        return;
    }
    vec2 axis = vec2(0.0);
    for (int k = 0; k < 8; k++) axis += corners[k + 8] - corners[k];
    vec2 u = dot(axis, axis) > EPS_SCREEN_AXIS2 ? normalize(axis) : vec2(1.0, 0.0);
    vec2 v = vec2(-u.y, u.x);
    vec2 lo = vec2(3e38);
    vec2 hi = vec2(-3e38);
    for (int k = 0; k < 16; k++) {
        vec2 w = vec2(dot(corners[k], u), dot(corners[k], v));
        lo = min(lo, w);
        hi = max(hi, w);
    }
    // one pixel of margin: a pixel whose centre lies outside may still send sub-pixel rays inside
    vec2 w = mix(lo - 1.0, hi + 1.0, in_quad);
    gl_Position = vec4((w.x * u + w.y * v) / halfViewport, 0.0, 1.0);
}
