#version 450 core
// ribbon.vert: one instance per (container segment, fiber): a 4-vertex strip, expanded sideways to face
// the camera by the fiber's radius. The fiber is P(t) = mix(p0, p1, t) + mix(r0, r1, t) * d, t in
// [t0, t1] (app/render/explicit.py says why this encoding); t0 == t1 gives no area (a fiber cut earlier).
// Positions are scene-relative float32 plus a float64-computed camera offset, as for the containers.
// TAPER 1: the fiber thins toward its own tip as the virtual one does (fibers/taper.glsl, the same
// function): its radius is fiber_radius * w * min(1, L(Z)), linear in the height on the root-width part
// and on the cone, so the strip has 6 vertices, a pair where the cone starts, and ends at the cone's apex.

#include "explicit/ring_of.glsl"
#ifndef TAPER
#define TAPER 0
#endif
#if TAPER
#include "fibers/taper.glsl"
#endif

in vec4 aRowA;                  // p0.xyz, r0       per segment row (attribute divisor = fibers per container)
in vec4 aRowB;                  // p1.xyz, r1
in vec4 aRowC;                  // n0.xyz, v0       root-side joint plane, guide parameter there
in vec4 aRowD;                  // n1.xyz, v1
in float aGuide;
in vec4 aFiber;                 // d.xyz, t0        per (segment, fiber)
in float aEnd;                  // t1
in uint aLook;                  // tint | roughness << 8, 8 bits each
#if TAPER
in float aFiberEnd;             // v_end: where along its guide the fiber ends
#endif

uniform vec3 uSceneFromCamera;  // scene origin minus camera position
uniform mat4 uClipFromCamera;   // projection * view rotation (camera at the origin)
uniform int uFibersPerContainer;
uniform float uRingRadius[MAX_RINGS];   // fiber radius by ring, a fraction of the container radius

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
flat out float vTilt;           // how fast the radius falls along the fiber (its cone; 0 on the root part)
flat out float vFiberRadius;    // the fiber's ring's radius (the clump profile thins the outer rings')

void main() {
    int row = gl_InstanceID / uFibersPerContainer;
    int inContainer = gl_InstanceID - row * uFibersPerContainer;
    int ring = ring_of(inContainer);
    vFiberRadius = uRingRadius[ring];
    int pair = gl_VertexID >> 1;
    vec3 axis = aRowB.xyz - aRowA.xyz;
    float h = length(axis);
    float width = 1.0;          // radius / (fiber_radius * w)
    vTilt = 0.0;
#if TAPER
    // the width line of this segment in unit height Z = z / w(z); z = r0 Z / (1 - kappa Z) undoes it
    float r0 = aRowA.w;
    float kappa = (aRowB.w - aRowA.w) / h;
    vec2 line = taper_line(taper_seg(aRowC.w, aRowD.w, h / (aRowD.w - aRowC.w), r0, kappa), aFiberEnd);
    float zOne = line.y < 0.0 ? (1.0 - line.x) / line.y : INF;      // where the cone is as wide as the root
    float zApex = taper_apex(line);
    float tOne = zOne < INF && 1.0 - kappa * zOne > 0.0 ? r0 * zOne / (1.0 - kappa * zOne) / h : INF;
    float tApex = zApex < INF && 1.0 - kappa * zApex > 0.0 ? r0 * zApex / (1.0 - kappa * zApex) / h : INF;
    float tEnd = max(aFiber.w, min(aEnd, tApex));
    float tKnee = clamp(tOne, aFiber.w, tEnd);
    float t = pair == 0 ? aFiber.w : (pair == 1 ? tKnee : tEnd);
    float zt = t * h;
    width = clamp(line.x + line.y * zt / (r0 + kappa * zt), 0.0, 1.0);
    // the cone's radius fiber_radius (l0 w + l1 z) falls by fiber_radius (l0 kappa + l1) per unit height;
    // per unit length along the fiber, |dP/dz| = |ez + kappa d|. Flat: the second quad's last vertices.
    vTilt = pair == 2 ? -vFiberRadius * (line.x * kappa + line.y) / length(axis / h + kappa * aFiber.xyz) : 0.0;
#else
    float t = pair == 0 ? aFiber.w : aEnd;
#endif
    float side = (gl_VertexID & 1) == 0 ? -1.0 : 1.0;
    vec3 d = aFiber.xyz;
    float w = mix(aRowA.w, aRowB.w, t);
    vec3 pCam = mix(aRowA.xyz, aRowB.xyz, t) + w * d + uSceneFromCamera;
    vec3 T = normalize(aRowB.xyz - aRowA.xyz + (aRowB.w - aRowA.w) * d);     // dP/dt
    vec3 across = cross(T, -pCam);
    float al = length(across);
    float halfWidth = al > 0.0 ? vFiberRadius * w * width / al : 0.0;

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
    vId = uvec4(uint(aGuide) + 1u, uint(ring), uint(inContainer - uRingFirst[ring]), uint(row));
    vLook = vec3(float(aLook & 0xffu) / 255.0, float(aLook >> 8) / 255.0, length(d));
    gl_Position = uClipFromCamera * vec4(vPos, 1.0);
}
