#version 450 core
// container.frag: per pixel, rebuild the view ray, enter the container's unit space, traverse the
// virtual fibers and write the nearest hit (colour, ids, normal, true depth) or discard.
// Variants (defines): COST_PASS writes the work done (fiber tests, arcs, 1, loop iterations) for additive
// blending instead; SUPERSAMPLE n traces n x n stratified rays per pixel and writes coverage as alpha;
// MSAA_SAMPLES n traces one ray per sample and sets gl_SampleMask (colour only);
// SHADING_MODEL 0 Kajiya-Kay, 1 Marschner; SHADOW_MODE 0 off, 1 density estimate, 2 traced shadow ray.

#include "fibers/traverse.glsl"
#include "shading/light.glsl"
#include "shading/kajiya_kay.glsl"
#include "shading/marschner.glsl"

flat in vec4 vSeg[7];       // the segment, packed by container.vert
flat in int vSegment;

uniform vec3 uCamRight;         // world-space camera basis, scaled by tan(fov/2) (and aspect)
uniform vec3 uCamUp;
uniform vec3 uCamForward;
uniform vec2 uViewport;
uniform vec2 uPixelOffset;      // sub-pixel offset of the ray (antialiasing, stability tests)
uniform float uNear;
uniform vec3 uBaseColor;        // linear; from RGB or from melanin (app/render/look.py)
uniform float uRoughness;
uniform float uTintVariation;
uniform float uRoughnessVariation;
uniform float uShadowDensity;
uniform float uFiberDensity;    // fiber cross-section per unit length of a light path, unit space
uniform vec2 uSampleOffsets[16];

#ifndef COST_PASS
#define COST_PASS 0
#endif
#ifndef SUPERSAMPLE
#define SUPERSAMPLE 1
#endif
#ifndef MSAA_SAMPLES
#define MSAA_SAMPLES 0
#endif
#ifndef SHADING_MODEL
#define SHADING_MODEL 0
#endif
#ifndef SHADOW_MODE
#define SHADOW_MODE 1
#endif

#if COST_PASS
layout(location = 0) out vec4 outCost;
#else
layout(location = 0) out vec4 outColor;     // premultiplied by coverage
#if MSAA_SAMPLES == 0
layout(location = 1) out uvec4 outId;       // guide + 1, ring, fiber, segment
layout(location = 2) out vec4 outGeom;      // world normal, distance along the ray
#endif
#endif

struct Shaded {
    bool hit;
    float t;
    vec3 color;
    vec3 N;
    uvec4 id;
};

// Depth of the hit, logarithmic in the distance so near 1e-4 and far 1e6 both resolve: 0 at uNear, 1 at
// the camera's far plane. One log2 per fragment: uDepthScale = 1 / log2(far / near), from the renderer.
uniform float uDepthScale;

float log_depth(float t) {
    return clamp(log2(max(t, uNear) / uNear) * uDepthScale, 0.0, 1.0);
}

vec3 view_ray(vec2 offset) {
    vec2 ndc = (gl_FragCoord.xy + offset) / uViewport * 2.0 - 1.0;
    return normalize(uCamForward + ndc.x * uCamRight + ndc.y * uCamUp);
}

// How much key light reaches the hit through the fibers between it and the container's surface.
float light_transmittance(Segment seg, UnitRay ur, FiberHit hit, vec3 L) {
#if SHADOW_MODE == 0
    return 1.0;
#else
    // the light direction in unit space at the hit (the projective map bends directions by position)
    vec3 Pu = ur.O + hit.s * ur.D;
    float w = seg.r0 / (1.0 - seg.kappa * Pu.z);
    vec3 Pl = Pu * w;
    vec3 Ll = transpose(mat3(seg.ex, seg.ey, seg.ez)) * L;
    vec3 Ql = Pl + Ll * (1e-3 * w);
    vec3 Qu = Ql / (seg.r0 + seg.kappa * Ql.z);
    UnitRay sr = ur;
    sr.O = Pu;
    sr.D = normalize(Qu - Pu);
    // Light leaves through the side wall, or past the guide's root or tip. A joint between two segments
    // is no boundary for light: stopping there would band every segment (the next one's fibers shade too).
    vec2 wall = circle_interval(sr.O.xy, sr.D.xy, vec2(0.0), 1.0);
    // (root and tip planes clipped into copies and selected: no branch, see intervals.glsl)
    vec2 root = vec2(0.0, wall.y);
    clip_half_space(sr.O, sr.D, -seg.r0 * seg.n0, 0.0, root.x, root.y);
    vec2 s = seg.v0 <= 0.0 ? root : vec2(0.0, wall.y);
    vec2 tip = s;
    clip_half_space(sr.O, sr.D, seg.r0 * seg.n1 + vec3(0.0, 0.0, seg.n1.z * seg.h * seg.kappa),
                    seg.n1.z * seg.h, tip.x, tip.y);
    s = seg.v1 >= 1.0 ? tip : s;
    sr.s0 = s.x;
    sr.s1 = s.y;
#if SHADOW_MODE == 1
    // density estimate: fibers as a uniform medium along the path to the container's surface
    return sr.s0 <= sr.s1 ? exp(-uShadowDensity * uFiberDensity * sr.s1) : 1.0;
#else
    if (!(sr.s0 <= sr.s1)) return 1.0;
    // traced: the same traversal, any fiber on the way blocks the light
    int mode = gMode;
    gMode = 0;
    gSkipRing = hit.ring;
    gSkipFiber = hit.fiber;
    FiberHit blocker = traverse(seg, sr);
    gMode = mode;
    gSkipRing = -1;
    gSkipFiber = -1;
    return blocker.s < INF ? 1.0 - uShadowDensity : 1.0;
#endif
#endif
}

// No early returns: a ray that misses still runs every statement (llvmpipe executes both sides of a
// branch anyway, and code after a return would pay a blend per assignment); o.hit says what counts.
Shaded trace_and_shade(Segment seg, vec3 rd, bool shade) {
    Shaded o;
    UnitRay ur;
    to_unit_space(seg, vec3(0.0), rd, uNear, ur);   // a miss leaves [s0, s1] empty: traverse finds nothing
    FiberHit hit = traverse(seg, ur);
    o.hit = hit.s < INF;
    hit.s = o.hit ? hit.s : 0.0;                // keep the arithmetic below finite on a miss
    o.t = unit_to_world_t(seg, ur, hit.s);
    o.id = uvec4(seg.guide + 1u, uint(hit.ring), uint(hit.fiber), uint(vSegment));

    vec3 P = ur.O + hit.s * ur.D;               // unit space
    // the side of a fiber; its cut tip; a fiber cut by a cap or joint (its section faces us)
    vec2 radial = P.xy - hit.c;
    vec3 nLocal = hit.kind == 0 ? vec3(radial, -seg.kappa * dot(radial, P.xy))
                : (hit.kind == 1 ? vec3(0.0, 0.0, 1.0) : -ur.d);
    mat3 worldFromLocal = mat3(seg.ex, seg.ey, seg.ez);
    vec3 N = normalize(worldFromLocal * nLocal);
    vec3 V = -rd;
    N = dot(N, V) < 0.0 ? -N : N;
    o.N = N;
    if (!shade) return o;

    // the fiber's direction: d/dz of (w(z) c(v(z)), z), w the local container radius at the hit. The
    // guide's own direction is blended from one joint plane's normal to the other's (each is the mean of
    // the two segments' axes), so a bent guide shades smoothly across its joints.
    float wHit = seg.r0 / (1.0 - seg.kappa * P.z);
    float zHit = P.z * wHit;
    vec3 axis = normalize(mix(seg.n0, seg.n1, clamp(zHit / seg.h, 0.0, 1.0)));
    vec2 slope = seg.kappa * hit.c + wHit * hit.dcdv * (seg.v1 - seg.v0) / seg.h;
    vec3 T = normalize(worldFromLocal * (axis + vec3(slope, 0.0)));

    uint key = fiber_key(uSeed, seg.guide, uint(hit.ring), uint(hit.fiber));
    float tint = key_random(key, CH_TINT) - 0.5;
    float rough = key_random(key, CH_ROUGH) - 0.5;
    vec3 color = clamp(uBaseColor * (1.0 + uTintVariation * 2.0 * tint), 0.0, 1.0);
    float roughness = clamp(uRoughness * (1.0 + uRoughnessVariation * 2.0 * rough), 0.02, 1.0);
    // fibers deep in the container see less of the sky
    float occlusion = mix(1.0, exp(-3.0 * (1.0 - length(hit.c))), uShadowDensity);
    ContainerShadow cs = ContainerShadow(transpose(worldFromLocal), hit.c,
                                         SHADOW_MODE == 0 ? 0.0 : uShadowDensity * uFiberDensity);
    vec3 radiance = shade_lights(T, N, V, color, roughness, occlusion,
                                 light_transmittance(seg, ur, hit, uLightDir), cs);
    o.color = tone_map(radiance);
    return o;
}

void main() {
    Segment seg = unpack_segment(vSeg);
#if COST_PASS
    UnitRay ur;
    if (!to_unit_space(seg, vec3(0.0), view_ray(uPixelOffset), uNear, ur)) discard;
    FiberHit hit = traverse(seg, ur);
    outCost = vec4(float(gTests), float(gPieces), 1.0, float(gIters));
#elif MSAA_SAMPLES > 0
    // one ray per sample decides coverage; only the first sample that hits is shaded (MSAA's bargain:
    // coverage at every sample, colour once per pixel), the nearest hit sets the depth
    int mask = 0;
    Shaded best;
    best.hit = false;
    for (int k = 0; k < MSAA_SAMPLES; k++) {
        Shaded s = trace_and_shade(seg, view_ray(uPixelOffset + uSampleOffsets[k]), !best.hit);
        if (!s.hit) continue;
        mask |= 1 << k;
        if (!best.hit) best = s;
        best.t = min(best.t, s.t);
    }
    if (mask == 0) discard;
    gl_SampleMask[0] = mask & gl_SampleMaskIn[0];
    gl_FragDepth = log_depth(best.t);
    outColor = vec4(best.color, 1.0);
#elif SUPERSAMPLE == 1
    // One ray per pixel, written out without a loop: llvmpipe runs every statement inside a loop under
    // lane masks (a blend per assignment), even a loop of one pass.
    Shaded s = trace_and_shade(seg, view_ray(uPixelOffset), true);
    if (!s.hit) discard;
    gl_FragDepth = log_depth(s.t);
    outColor = vec4(s.color, 1.0);
    outId = s.id;
    outGeom = vec4(s.N, s.t);
#else
    // SUPERSAMPLE x SUPERSAMPLE stratified rays; the nearest hit names the pixel's fiber and depth
    vec3 sum = vec3(0.0);
    int hits = 0;
    Shaded nearest;
    nearest.hit = false;
    nearest.t = INF;
    for (int k = 0; k < SUPERSAMPLE * SUPERSAMPLE; k++) {
        vec2 cell = (vec2(k % SUPERSAMPLE, k / SUPERSAMPLE) + 0.5) / float(SUPERSAMPLE) - 0.5;
        Shaded s = trace_and_shade(seg, view_ray(uPixelOffset + cell), true);
        if (!s.hit) continue;
        hits++;
        sum += s.color;
        if (s.t < nearest.t) nearest = s;
    }
    if (hits == 0) discard;
    // the true depth of the fiber inside the container (logarithmic: near 1e-4 and far 1e6 both work)
    gl_FragDepth = log_depth(nearest.t);
    float coverage = float(hits) / float(SUPERSAMPLE * SUPERSAMPLE);
    outColor = vec4(sum / float(SUPERSAMPLE * SUPERSAMPLE), coverage);
    outId = nearest.id;
    outGeom = vec4(nearest.N, nearest.t);
#endif
}
