#version 450 core
// ribbon.vert: one triangle strip per explicit fiber, expanded sideways to face the camera.
// Strip vertex q of fiber f (2 (S + 1) + 2 per fiber): q - 1 clamped is 2 k + side; the first and last
// vertices repeat their neighbours so consecutive fibers join by degenerate triangles in one draw.
// Vertices past the fiber's last one (k_end) collapse onto it: same inputs, same outputs, no area.

#include "explicit/strands.glsl"
#include "fibers/layout.glsl"

uniform vec3 uSceneFromCamera;  // scene origin minus camera position
uniform mat4 uClipFromCamera;   // projection * view rotation (camera at the origin)
uniform int uStripVertices;     // 2 (S + 1) + 2
uniform int uFiberBase;         // group-relative index of the chunk's first fiber
uniform uint uChainBase;        // first chain of the group
uniform int uFibersPerContainer;

out vec3 vPos;                  // camera-relative position on the ribbon
out vec3 vTangent;
out float vAcross;              // -1 .. 1 across the ribbon
flat out uvec4 vId;             // guide + 1, ring, fiber, segment row
flat out vec3 vLook;            // tint, roughness (0 .. 1), |c|

// Ring of a fiber from its index in the container's flat numbering (uRingN.y: each ring's first fiber).
int ring_of(int f) {
    int lo = 0;
    int hi = uRings - 1;
    while (lo < hi) {
        int mid = (lo + hi + 1) >> 1;
        if (uRingN[mid].y <= f) lo = mid; else hi = mid - 1;
    }
    return lo;
}

void main() {
    int fiber = gl_VertexID / uStripVertices;               // within the bound chunk
    int q = clamp(gl_VertexID - fiber * uStripVertices - 1, 0, uStripVertices - 3);
    int fg = uFiberBase + fiber;                             // within the group
    uvec4 ch = chain[uChainBase + uint(fg / uFibersPerContainer)];
    int inContainer = fg % uFibersPerContainer;

    uint record = strand_record(fiber);
    int kEnd = int(record >> 16);
    int k = min(q >> 1, kEnd);
    float side = (q & 1) == 0 ? -1.0 : 1.0;

    // this vertex and its neighbours along the fiber (one-sided at the ends)
    Strand here = strand_at(fiber, k, ch.x);
    vec3 prev = k > 0 ? strand_at(fiber, k - 1, ch.x).p : here.p;
    vec3 next = k < kEnd ? strand_at(fiber, k + 1, ch.x).p : here.p;
    vec3 pCam = here.p + uSceneFromCamera;
    vec3 t = next - prev;
    float tl = length(t);
    vec3 T = tl > 0.0 ? t / tl : vec3(0.0, 0.0, 1.0);
    vec3 V = -pCam;                                          // toward the camera
    vec3 across = cross(T, V);
    float al = length(across);
    float halfWidth = (tl > 0.0 && al > 0.0) ? uFiberRadius * here.w : 0.0;
    across = al > 0.0 ? across / al : vec3(0.0);

    vPos = pCam + side * halfWidth * across;
    vTangent = T;
    vAcross = side;
    int ring = ring_of(inContainer);
    int segment = max(k - 1, 0);                             // the provoking (last) vertex names the segment
    vId = uvec4(ch.z + 1u, uint(ring), uint(inContainer - uRingN[ring].y), ch.y + uint(segment));
    vLook = vec3(float(record & 0xffu) / 255.0, float((record >> 8) & 0xffu) / 255.0, here.c);
    gl_Position = uClipFromCamera * vec4(vPos, 1.0);
}
