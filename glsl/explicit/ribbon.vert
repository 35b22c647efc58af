#version 450 core
// ribbon.vert: one instance per (container segment, fiber): a 4-vertex strip, expanded sideways to face
// the camera by the fiber's radius. The fiber is P(t) = mix(p0, p1, t) + mix(r0, r1, t) * d, t in
// [t0, t1] (app/render/explicit.py says why this encoding); t0 == t1 gives no area (a fiber cut earlier).
// Positions are scene-relative float32 plus a float64-computed camera offset, as for the containers.
// TAPER 1: the fiber thins toward its own tip as the virtual one does (fibers/taper.glsl, the same
// function): its radius is fiber_radius * w * min(1, L(Z)), linear in the height on the root-width part
// and on the cone, so the strip has 6 vertices, a pair where the cone starts, and ends at the cone's apex.
// FILTER 1 (quality.filter = coverage, the filtered passes of app/render/explicit.py): the ribbon is widened
// by the footprint, a tent of half-width uFootprint * distance across it (fibers/coverage.glsl's), so every
// pixel the footprint of the fiber reaches gets a fragment; ribbon.frag turns its place across into the
// share of the footprint the fiber covers.

#include "explicit/ring_of.glsl"
#ifndef TAPER
#define TAPER 0
#endif
#define LAST_PAIR (TAPER == 0 ? 1 : 2)
#ifndef FILTER
#define FILTER 0
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
uniform float uFootprint;       // FILTER: the footprint's half-width per unit distance (fibers/coverage.glsl)

out vec3 vPos;                  // camera-relative position on the ribbon
out vec3 vTangent;              // the fiber's direction, as the ribbon runs
out vec2 vJoint;                // the axis point's distance from the root and tip joint planes (shading)
flat out vec3 vJointN0;         // the joint planes' normals: the shading direction blends between them
flat out vec3 vJointN1;
flat out vec3 vSlope;           // the fiber's lean from its container's axis per unit height (taper)
out float vAcross;              // -1 .. 1 across the ribbon
out vec4 vInside;               // the axis point's offset from the container axis (w d), local height z
out float vRadius;              // container radius w there
flat out vec4 vAxis;            // segment axis (unit) and length h: for the self-shadow path
flat out vec2 vEnds;            // 1 where the segment is the guide's root / tip: light leaves there
flat out vec2 vRadii;           // the container's radius at the segment's root and tip end
flat out uvec4 vId;             // guide + 1, ring, fiber, segment row
flat out vec3 vLook;            // tint, roughness (0 .. 1), |c|
out float vV;                   // guide parameter (0 root .. 1 tip): the colour along the strand
flat out float vTilt;           // how fast the radius falls along the fiber (its cone; 0 on the root part)
flat out float vFiberRadius;    // the fiber's ring's radius (the clump profile thins the outer rings')
out vec3 vCross;                // FILTER: offset across the fiber, its radius and the footprint's half-width
                                // (world units at the fragment: x, r, w of footprint_coverage)

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
    vec3 dPdt = aRowB.xyz - aRowA.xyz + (aRowB.w - aRowA.w) * d;
    vec3 T = normalize(dPdt);
    // A fiber kinks at a joint, and a ribbon cut square to its own direction would leave a wedge open on
    // the bend's outer side and overlap the next segment's ribbon on the inner side (seams along every
    // joint). So the corner of a ribbon end on a joint plane that falls short of the plane is lengthened
    // along the fiber to reach it, and both planes clip the ribbon (gl_ClipDistance): two segments'
    // ribbons meet on the plane, as the virtual fibers do. A fiber's own end (cut inside the segment) is
    // no plane and stays square.
    vec3 onAxis = mix(aRowA.xyz, aRowB.xyz, t) + mix(aRowA.w, aRowB.w, t) * d;
    vec3 toEye = -(onAxis + uSceneFromCamera);
    vec3 acrossDir = cross(T, toEye) / max(length(cross(T, toEye)), 1e-30);
    float grown = float(FILTER != 0) * uFootprint * length(toEye);
    vec3 corner = onAxis + side * (vFiberRadius * mix(aRowA.w, aRowB.w, t) * width + grown) * acrossDir;
    float tol = 2e-3 * h;       // half-float t0, t1: within ~5e-4 h of the plane they were cut at
    float grow = 0.0;
    if (pair == 0 && abs(dot(aRowC.xyz, onAxis - aRowA.xyz)) < tol)
        grow = -max(dot(aRowC.xyz, corner - aRowA.xyz), 0.0) / max(dot(aRowC.xyz, T), 0.25);
    if (pair == LAST_PAIR && abs(dot(aRowD.xyz, aRowB.xyz - onAxis)) < tol)
        grow = max(dot(aRowD.xyz, aRowB.xyz - corner), 0.0) / max(dot(aRowD.xyz, T), 0.25);
    t += grow / length(dPdt);
    float w = mix(aRowA.w, aRowB.w, t);
    vec3 pCam = mix(aRowA.xyz, aRowB.xyz, t) + w * d + uSceneFromCamera;
    vec3 across = cross(T, -pCam);
    float al = length(across);
    float radius = vFiberRadius * w * width;
    float footprint = float(FILTER != 0) * uFootprint * length(pCam);
    float halfWidth = al > 0.0 ? (radius + footprint) / al : 0.0;
    vCross = vec3(side * (radius + footprint), radius, footprint);

    vAxis = vec4(axis / h, h);
    vEnds = vec2(aRowC.w <= 0.0 ? 1.0 : 0.0, aRowD.w >= 1.0 ? 1.0 : 0.0);
    vRadii = vec2(aRowA.w, aRowB.w);
    // shading/fiber_shading.glsl: the guide's direction blended between the joint planes by where the
    // point lies between them (shading/tangent.glsl), plus the taper's tilt of an off-axis fiber. Both
    // distances are linear along the fiber, so the rasterizer interpolates them exactly.
    onAxis = mix(aRowA.xyz, aRowB.xyz, t) + w * d;
    vJoint = vec2(dot(aRowC.xyz, onAxis - aRowA.xyz), dot(aRowD.xyz, aRowB.xyz - onAxis));
    vJointN0 = aRowC.xyz;
    vJointN1 = aRowD.xyz;
    vSlope = (aRowB.w - aRowA.w) / h * d;
    vInside = vec4(w * d, t * h);
    vRadius = w;
    vV = mix(aRowC.w, aRowD.w, t);
    vPos = pCam + side * halfWidth * across;
    vTangent = T;
    vAcross = side;
    vId = uvec4(uint(aGuide) + 1u, uint(ring), uint(inContainer - uRingFirst[ring]), uint(row));
    vLook = vec3(float(aLook & 0xffu) / 255.0, float(aLook >> 8) / 255.0, length(d));
    gl_Position = uClipFromCamera * vec4(vPos, 1.0);
    vec3 P = vPos - uSceneFromCamera;
    gl_ClipDistance[0] = dot(aRowC.xyz, P - aRowA.xyz);
    gl_ClipDistance[1] = dot(aRowD.xyz, aRowB.xyz - P);
}
