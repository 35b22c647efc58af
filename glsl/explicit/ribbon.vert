#version 450 core
// ribbon.vert: one instance per (container segment, fiber): a 4-vertex strip, expanded sideways to face
// the camera by the fiber's radius. The fiber is P(t) = mix(p0, p1, t) + mix(r0, r1, t) * d, t in
// [t0, t1] (app/render/explicit.py says why this encoding); t0 == t1 gives no area (a fiber cut earlier).
// Positions are scene-relative float32 plus a float64-computed camera offset, as for the containers.

#include "explicit/ring_of.glsl"

in vec4 aRowA;                  // p0.xyz, r0       per segment row (attribute divisor = fibers per container)
in vec4 aRowB;                  // p1.xyz, r1
in vec4 aRowC;                  // n0.xyz, v0       root-side joint plane, guide parameter there
in vec4 aRowD;                  // n1.xyz, v1
in float aGuide;
in vec4 aFiber;                 // d.xyz, t0        per (segment, fiber)
in float aEnd;                  // t1
in uint aLook;                  // tint | roughness << 8, 8 bits each

uniform vec3 uSceneFromCamera;  // scene origin minus camera position
uniform mat4 uClipFromCamera;   // projection * view rotation (camera at the origin)
uniform int uFibersPerContainer;
uniform float uFiberRadius;     // fraction of the container radius

out vec3 vPos;                  // camera-relative position on the ribbon
out vec3 vTangent;              // the fiber's direction, as the ribbon runs
out vec3 vShadeTangent;         // the direction the virtual renderer shades with (joint-blended guide axis)
out float vAcross;              // -1 .. 1 across the ribbon
out vec4 vInside;               // the axis point's offset from the container axis (w d), local height z
out float vRadius;              // container radius w there
flat out vec4 vAxis;            // segment axis (unit) and length h: for the self-shadow path
flat out vec2 vEnds;            // 1 where the segment is the guide's root / tip: light leaves there
flat out uvec4 vId;             // guide + 1, ring, fiber, segment row
flat out vec3 vLook;            // tint, roughness (0 .. 1), |c|
out float vV;                   // guide parameter (0 root .. 1 tip): the colour along the strand

void main() {
    float t = (gl_VertexID >> 1) == 0 ? aFiber.w : aEnd;
    float side = (gl_VertexID & 1) == 0 ? -1.0 : 1.0;
    vec3 d = aFiber.xyz;
    float w = mix(aRowA.w, aRowB.w, t);
    vec3 pCam = mix(aRowA.xyz, aRowB.xyz, t) + w * d + uSceneFromCamera;
    vec3 T = normalize(aRowB.xyz - aRowA.xyz + (aRowB.w - aRowA.w) * d);     // dP/dt
    vec3 across = cross(T, -pCam);
    float al = length(across);
    float halfWidth = al > 0.0 ? uFiberRadius * w / al : 0.0;

    vec3 axis = aRowB.xyz - aRowA.xyz;
    float h = length(axis);
    vAxis = vec4(axis / h, h);
    vEnds = vec2(aRowC.w <= 0.0 ? 1.0 : 0.0, aRowD.w >= 1.0 ? 1.0 : 0.0);
    // stages/container.frag: the guide's direction blended from one joint plane's normal to the other's
    // (each the mean of two segments' axes), plus the taper's tilt of an off-axis fiber
    vShadeTangent = normalize(normalize(mix(aRowC.xyz, aRowD.xyz, t)) + (aRowB.w - aRowA.w) / h * d);
    vInside = vec4(w * d, t * h);
    vRadius = w;
    vV = mix(aRowC.w, aRowD.w, t);
    vPos = pCam + side * halfWidth * across;
    vTangent = T;
    vAcross = side;
    int row = gl_InstanceID / uFibersPerContainer;
    int inContainer = gl_InstanceID - row * uFibersPerContainer;
    int ring = ring_of(inContainer);
    vId = uvec4(uint(aGuide) + 1u, uint(ring), uint(inContainer - uRingFirst[ring]), uint(row));
    vLook = vec3(float(aLook & 0xffu) / 255.0, float(aLook >> 8) / 255.0, length(d));
    gl_Position = uClipFromCamera * vec4(vPos, 1.0);
}
