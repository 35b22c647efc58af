#version 330 core
// clear.frag: clear the renderer's three targets (colour, integer ids, geometry) and its depth in one
// fullscreen pass. glClear is undefined on integer attachments and uploading zeros from the CPU costs a
// 33 MB copy per 1280x720 frame; a draw costs one pass of the rasterizer.

layout(location = 0) out vec4 outColor;
layout(location = 1) out uvec4 outId;
layout(location = 2) out vec4 outGeom;

void main() {
    outColor = vec4(0.0);
    outId = uvec4(0u);
    outGeom = vec4(0.0);
    gl_FragDepth = 1.0;
}
