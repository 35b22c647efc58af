#version 330 core
// proxy.vert: the container proxies as wireframes, generated from the segment records alone (the same
// per-instance data the renderer draws from; see app/scene/containers.py for the layout).
// Per instance, as GL_LINES: the two end ellipses (the cylinder cut by its miter planes n0 and n1,
// N_SIDES edges each) and 4 lines along the sides. Vertex count per instance: 4 * N_SIDES + 8.
// Positions are camera-relative (uSceneFromCamera computed in float64), as in container.vert.

#include "common/epsilon.glsl"

#define N_SIDES 16

in vec4 in_a;               // p0.xyz, r0
in vec4 in_b;               // p1.xyz, r1
in vec4 in_c;               // n0.xyz, v0
in vec4 in_d;               // n1.xyz, v1
in vec4 in_e;               // frame x, guide

uniform vec3 uSceneFromCamera;
uniform mat4 uClipFromCamera;

flat out float vGuide;

// A point on the rim of end `e` (0 root, 1 tip) at angle `phi`: the circle of radius r about the axis,
// slid along the axis onto the end's miter plane.
vec3 rim(int e, float phi) {
    vec3 p = e == 0 ? in_a.xyz : in_b.xyz;
    float r = e == 0 ? in_a.w : in_b.w;
    vec3 n = e == 0 ? in_c.xyz : in_d.xyz;
    vec3 axis = normalize(in_b.xyz - in_a.xyz);
    vec3 fy = cross(axis, in_e.xyz);
    vec3 radial = r * (cos(phi) * in_e.xyz + sin(phi) * fy);
    float slide = -dot(n, radial) / max(dot(n, axis), EPS_PROXY_JOINT_COS);
    return p + radial + slide * axis;
}

void main() {
    const float TAU = 6.28318530718;
    int v = gl_VertexID;
    vec3 pScene;
    if (v < 4 * N_SIDES) {                       // end ellipses: edge k of end e, vertex 0 or 1
        int e = v / (2 * N_SIDES);
        int k = (v % (2 * N_SIDES)) / 2 + (v & 1);
        pScene = rim(e, TAU * float(k) / float(N_SIDES));
    } else {                                     // side lines at 0, 90, 180, 270 degrees
        int w = v - 4 * N_SIDES;
        pScene = rim(w & 1, TAU * 0.25 * float(w / 2));
    }
    vGuide = in_e.w;
    gl_Position = uClipFromCamera * vec4(pScene + uSceneFromCamera, 1.0);
}
