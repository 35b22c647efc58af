#version 330 core
// fullscreen.vert: one triangle over the whole viewport, no vertex buffer (gl_VertexID 0, 1, 2).
// Out: vUv in [0, 1]^2 over the viewport (texture coordinates, GL orientation: row 0 at the bottom).

out vec2 vUv;

void main() {
    vec2 corner = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
    vUv = corner;
    gl_Position = vec4(corner * 2.0 - 1.0, 0.0, 1.0);
}
