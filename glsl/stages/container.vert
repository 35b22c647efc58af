#version 450 core
// container.vert: rasterize each container segment as a tight oriented box (its proxy). The box is
// placed camera-relative: positions are scene-relative float32 plus a float64-computed camera offset.

in vec3 in_corner;          // unit cube corner in [-1, 1]^3
in vec4 in_a;               // p0.xyz, r0
in vec4 in_b;               // p1.xyz, r1
in vec4 in_c;               // n0.xyz, v0
in vec4 in_d;               // n1.xyz, v1
in vec4 in_e;               // frame x, guide

uniform vec3 uSceneFromCamera;  // scene origin minus camera position
uniform mat4 uClipFromCamera;   // projection * view rotation (camera at the origin)

flat out vec4 vA;
flat out vec4 vB;
flat out vec4 vC;
flat out vec4 vD;
flat out vec4 vE;
flat out int vSegment;

#include "geometry/container.glsl"

void main() {
    vA = vec4(in_a.xyz + uSceneFromCamera, in_a.w);
    vB = vec4(in_b.xyz + uSceneFromCamera, in_b.w);
    vC = in_c;
    vD = in_d;
    vE = in_e;
    vSegment = gl_InstanceID;
    Segment seg = make_segment(vA, vB, vC, vD, vE);
    float r = seg.rBound * (1.0 + 4.0 * EPS_BOUND);
    float z = mix(seg.zLo, seg.zHi, 0.5 * in_corner.z + 0.5);
    vec3 p = seg.p0 + seg.ex * (in_corner.x * r) + seg.ey * (in_corner.y * r) + seg.ez * z;
    gl_Position = uClipFromCamera * vec4(p, 1.0);
}
