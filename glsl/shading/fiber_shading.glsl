// fiber_shading.glsl: the colour, normal and ids of a fiber hit, and the light that reaches it
// (the fiber's albedo along its strand: fiber_color.glsl).
//   Shaded shade_fiber_hit(Segment seg, UnitRay ur, FiberHit hit, vec3 rd, uint segIndex, bool shade)
//   Shaded shade_fiber_at(Segment seg, UnitRay ur, FiberHit hit, vec3 P, vec4 given, vec3 rd,
//                         uint segIndex, bool shade)   at a given point, with given randoms (tint, rough)
//                         and, where given.z >= 0, the key light's transmittance and the occlusion
//                         (given.zw): the filtered mode's blended fiber (fibers/coverage.glsl)
//   float  light_transmittance(Segment seg, UnitRay ur, FiberHit hit, vec3 Pu, vec3 L)   Pu: the hit, unit space
// SHADING_MODEL 0 Kajiya-Kay, 1 Marschner; SHADOW_MODE 0 off, 1 density estimate, 2 traced shadow ray
// (the same traversal, any hit, inside the hit's container).

#ifndef SHADING_FIBER_SHADING_GLSL
#define SHADING_FIBER_SHADING_GLSL

#include "common/epsilon.glsl"
#include "fibers/traverse.glsl"
#include "shading/light.glsl"
#include "shading/kajiya_kay.glsl"
#include "shading/marschner.glsl"
#include "shading/fiber_color.glsl"
#include "shading/tangent.glsl"

#ifndef SHADING_MODEL
#define SHADING_MODEL 0
#endif
#ifndef SHADOW_MODE
#define SHADOW_MODE 1
#endif

uniform float uRoughness;
uniform float uRoughnessVariation;
uniform float uShadowDensity;
uniform float uFiberDensity;    // fiber cross-section per unit length of a light path, unit space

struct Shaded {
    bool hit;
    float t;
    vec3 color;
    vec3 linear;    // color before the display gamma (the filtered mode composites it)
    vec3 N;
    uvec4 id;
};

// How much key light reaches the hit through the fibers between it and the container's surface.
float light_transmittance(Segment seg, UnitRay ur, FiberHit hit, vec3 Pu, vec3 L) {
#if SHADOW_MODE == 0
    return 1.0;
#else
    // the light direction in unit space at the hit Pu (the projective map bends directions by position)
    float w = seg.r0 / (1.0 - seg.kappa * Pu.z);
    vec3 Pl = Pu * w;
    vec3 Ll = transpose(mat3(seg.ex, seg.ey, seg.ez)) * L;
#if SHADOW_MODE == 1
    // density estimate: fibers as a uniform medium along the path to the wall of the blended guide's
    // cylinder, which runs on across joints (tangent.glsl: joint_light_path), or past the root or tip
    float path = joint_light_path(seg.n0, seg.n1, vec3(0.0, 0.0, seg.h), vec2(seg.r0, seg.r0 + seg.kappa * seg.h),
                                  bvec2(seg.v0 <= 0.0, seg.v1 >= 1.0), Pl, Ll);
    return exp(-uShadowDensity * uFiberDensity * path);
#else
    vec3 Ql = Pl + Ll * (EPS_SHADOW_START * w);
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
Shaded shade_fiber_at(Segment seg, UnitRay ur, FiberHit hit, vec3 P, vec4 given, vec3 rd,
                      uint segIndex, bool shade) {
    float tint = given.x;
    float rough = given.y;
    Shaded o;
    o.hit = hit.s < INF;
    hit.s = o.hit ? hit.s : 0.0;                // keep the arithmetic below finite on a miss
    o.t = unit_to_world_t(seg, ur, hit.s);
    o.id = uvec4(seg.guide + 1u, uint(hit.ring), uint(hit.fiber), segIndex);

    // the side of a fiber; its cut tip; a fiber cut by a cap or joint (its section faces us)
    vec2 radial = P.xy - hit.c;
    vec3 nLocal = hit.kind == 0 ? vec3(radial, -seg.kappa * dot(radial, P.xy))
                : (hit.kind == 1 ? vec3(0.0, 0.0, 1.0) : -ur.d);
#if TAPER
    // the side of a tapered part (kind 3) leans toward the cone's apex (taper.glsl: taper_normal_z)
    vec2 cRest;
    float vEndHit;
    fiber_center(seg.guide, max(hit.ring, 0), max(hit.fiber, 0), cRest, vEndHit);
    vec2 line = taper_line(taper_seg(seg.v0, seg.v1, seg.h / (seg.v1 - seg.v0), seg.r0, seg.kappa), vEndHit);
    nLocal = hit.kind == 3 ? vec3(radial, -seg.kappa * dot(radial, P.xy)
                                          + taper_normal_z(uFiberRadius * line.y, length(radial), P.z, seg.kappa)) : nLocal;
#endif
    mat3 worldFromLocal = mat3(seg.ex, seg.ey, seg.ez);
    vec3 N = normalize(worldFromLocal * nLocal);
    vec3 V = -rd;
    N = dot(N, V) < 0.0 ? -N : N;
    o.N = N;
    if (!shade) return o;

    // the fiber's direction: d/dz of (w(z) c(v(z)), z), w the local container radius at the hit; the
    // guide's own direction is blended between the joint planes (tangent.glsl), so a bent guide shades
    // smoothly across its joints
    float wHit = seg.r0 / (1.0 - seg.kappa * P.z);
    vec3 axis = joint_blended_axis(seg.n0, seg.n1, seg.h, P * wHit);
    vec2 slope = seg.kappa * hit.c + wHit * hit.dcdv * (seg.v1 - seg.v0) / seg.h;
    vec3 T = normalize(worldFromLocal * (axis + vec3(slope, 0.0)));
    // the normal turns from the straight fiber's direction with it; a section cut by a cap or joint faces
    // the ray and keeps that
    vec3 Ns = hit.kind == 2 ? N : turn_with(N, normalize(worldFromLocal * vec3(slope, 1.0)), T);

    vec3 color = fiber_color(seg.guide, unit_to_v(seg, P.z), tint);
    float roughness = clamp(uRoughness * (1.0 + uRoughnessVariation * 2.0 * rough), 0.02, 1.0);
    // fibers deep in the container see less of the sky
    float occlusion = given.z >= 0.0 ? given.w : mix(1.0, exp(-3.0 * (1.0 - length(hit.c))), uShadowDensity);
    ContainerShadow cs = ContainerShadow(transpose(worldFromLocal), hit.c,
                                         SHADOW_MODE == 0 ? 0.0 : uShadowDensity * uFiberDensity);
    vec3 radiance = shade_lights(T, Ns, V, color, roughness, occlusion,
                                 given.z >= 0.0 ? given.z : light_transmittance(seg, ur, hit, P, uLightDir), cs);
    o.linear = tone_map_linear(radiance);
    o.color = pow(o.linear, vec3(1.0 / 2.2));
    return o;
}

// The nearest fiber's colour: its hit point, its own randoms.
Shaded shade_fiber_hit(Segment seg, UnitRay ur, FiberHit hit, vec3 rd, uint segIndex, bool shade) {
    float s = hit.s < INF ? hit.s : 0.0;        // keep the arithmetic finite on a miss
    uint key = fiber_key(uSeed, seg.guide, uint(hit.ring), uint(hit.fiber));
    vec4 given = vec4(key_random(key, CH_TINT) - 0.5, key_random(key, CH_ROUGH) - 0.5, -1.0, -1.0);
    return shade_fiber_at(seg, ur, hit, ur.O + s * ur.D, given, rd, segIndex, shade);
}


#endif
