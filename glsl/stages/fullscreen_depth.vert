#version 330 core
// fullscreen_depth.vert: one triangle over the whole viewport at window depth uDepth, no vertex buffer,
// so the depth test can choose which pixels a fullscreen pass runs on (renderer.py: the walk passes).

uniform float uDepth;           // window depth in [0, 1]

void main() {
    vec2 corner = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
    gl_Position = vec4(corner * 2.0 - 1.0, uDepth * 2.0 - 1.0, 1.0);
}
