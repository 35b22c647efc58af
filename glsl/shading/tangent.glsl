// tangent.glsl: the direction a bent guide is shaded with.
//   vec3 joint_blended_axis(vec3 n0, vec3 n1, float h, vec3 Pl)   at a point of the segment's local frame
//   vec3 joint_blend(vec3 n0, vec3 n1, float d0, float d1)       given the point's distances from the planes
//   vec3 turn_with(vec3 v, vec3 a, vec3 b)     v turned by the smallest rotation taking unit a to unit b
//   float joint_light_path(vec3 n0, vec3 n1, vec3 tip, vec2 radii, bvec2 open, vec3 P, vec3 L)
//                                              the density self-shadow's path, run on across joints
// A container segment is straight, but its guide bends at every joint, and a highlight at low roughness
// follows the tangent to a fraction of a degree. So shading does not take the segment's own axis: it
// blends from the root joint plane's normal n0 to the tip's n1 (each the mean of the two segments' axes
// that meet there: scene/containers.py) by where the point lies between the two planes, its distance
// from each along their normals. On a joint plane the blend is that plane's normal from either segment,
// so every fiber's tangent runs on across the joint. Blending by the height z / h instead gives a fiber
// off the axis, where a tilted joint plane sits higher or lower than the axis's end, a different weight
// on each side: a step of a few degrees at every joint, which cut low-roughness highlights into one dash
// per segment (docs/antialias.md, "Low roughness"). Shading only: hits, ids and depth do not read it.
// Users: fiber_shading.glsl (virtual fibers), explicit/ribbon.frag (the baseline); OSL twin:
// osl/stages/container.osl (the Kajiya-Kay closure's tangent).
// The shading normal turns with it (turn_with: the fiber's own direction onto the blended one), or the
// normal would still kink at every joint with the straight fibers: at a miter joint the two segments'
// surfaces meet mirrored across the joint plane, whose normal both tangents reach there, so both turned
// normals are one vector on the plane (tests/render/test_shading_tangent.py checks it).

#include "common/epsilon.glsl"

#ifndef SHADING_TANGENT_GLSL
#define SHADING_TANGENT_GLSL

// d0, d1: the point's distance from the root plane and from the tip plane (both >= 0 inside the segment);
// the weight of the tip plane's side: 0 on the root plane, 1 on the tip plane
float joint_weight(float d0, float d1) {
    d0 = max(d0, 0.0);
    d1 = max(d1, 0.0);
    return d0 + d1 > 0.0 ? d0 / (d0 + d1) : 0.5;
}

vec3 joint_blend(vec3 n0, vec3 n1, float d0, float d1) {
    return normalize(mix(n0, n1, joint_weight(d0, d1)));
}

// Pl: the point in the segment's local frame (root end at the origin, axis z, length h); n0 points into
// the segment, n1 out of it, both in that frame.
vec3 joint_blended_axis(vec3 n0, vec3 n1, float h, vec3 Pl) {
    return joint_blend(n0, n1, dot(n0, Pl), dot(n1, vec3(0.0, 0.0, h) - Pl));
}

// v turned by the smallest rotation that takes the unit vector a to the unit vector b (Rodrigues; a and b
// are a fiber's direction and its blended tangent, never opposite).
vec3 turn_with(vec3 v, vec3 a, vec3 b) {
    vec3 k = cross(a, b);
    float c = dot(a, b);
    return v * c + cross(k, v) + k * (dot(k, v) / max(1.0 + c, 1e-6));
}

// The key light's path from P along the unit direction L to the container's wall, in container radii, for
// the density self-shadow. Each segment's own straight cylinder met the next one's at a joint at another
// angle to the light, so the shadow stepped there (docs/antialias.md, "Low roughness"). Here the point's
// offset from the segment's axis is turned with the guide (turn_with: the axis onto joint_blend's
// direction) and the wall is the cylinder about that direction of the radius at the point's height. On a
// joint plane the two segments' offsets are mirror images across the plane whose normal both axes turn to,
// so both turned offsets are one vector and the path runs on across the joint; the offset keeps its length,
// so a point inside the container stays inside its wall; on a straight guide it is the segment's own
// cylinder. Light also leaves past the guide's root or tip where the segment is its first or last (open).
// The frame: the segment's root axis point at the origin, its tip axis point at `tip`; n0 into the segment,
// n1 out of it; radii at the root and the tip.
struct LightFrame {
    mat3 turn;          // the segment's axis onto the blended direction a, about their common normal
    vec3 Lp;            // the light's part square to a
    float dd;           // |Lp|^2
};

// The frame joint_light_path takes at P: the blended direction there and the turn onto it.
LightFrame joint_light_frame(vec3 n0, vec3 n1, vec3 tip, vec3 P, vec3 L) {
    vec3 axis = normalize(tip);
    vec3 a = normalize(mix(n0, n1, joint_weight(dot(n0, P), dot(n1, tip - P))));
    LightFrame f;
    f.turn = mat3(turn_with(vec3(1.0, 0.0, 0.0), axis, a), turn_with(vec3(0.0, 1.0, 0.0), axis, a),
                  turn_with(vec3(0.0, 0.0, 1.0), axis, a));
    f.Lp = L - a * dot(a, L);
    f.dd = dot(f.Lp, f.Lp);
    return f;
}

// How far the light's line from q (an offset turned by the frame, c = |q|^2 - w^2 for a wall of radius w)
// runs along L to the wall: the larger root of |q + t Lp| = w (INF for a light along the blended axis).
float joint_light_wall(LightFrame f, vec3 q, float c) {
    float b = dot(q, f.Lp);
    return f.dd > EPS_LIGHT_AXIS2 ? (-b + sqrt(max(b * b - f.dd * c, 0.0))) / f.dd : INF;
}

// The path from P, whose offset from the segment's axis is `offset`, in a frame taken at P. The offset is
// turned whole: the explicit reference's interpolated strands store a depth along the axis in it (app/bench/
// strand_reference.py: "at depth 1, on the wall"), whose length counts as a distance from the axis.
float joint_light_path_in(LightFrame f, vec3 n0, vec3 n1, vec3 tip, vec2 radii, bvec2 open, vec3 P, vec3 offset,
                          vec3 L) {
    float h = length(tip);
    vec3 axis = tip / max(h, EPS_DIVISOR);
    float z = dot(axis, P);
    vec3 q = f.turn * offset;
    float w = mix(radii.x, radii.y, clamp(z / max(h, EPS_DIVISOR), 0.0, 1.0));
    float side = joint_light_wall(f, q, dot(q, q) - w * w);
    float d0 = dot(n0, P);
    float d1 = dot(n1, tip - P);
    float along0 = dot(n0, L);
    float along1 = dot(n1, L);
    float root = open.x && along0 < 0.0 ? max(d0, 0.0) / -along0 : INF;
    float end = open.y && along1 > 0.0 ? max(d1, 0.0) / along1 : INF;
    float path = max(min(side, min(root, end)), 0.0);
    return path < INF ? path / max(w, EPS_DIVISOR) : INF;
}

float joint_light_path(vec3 n0, vec3 n1, vec3 tip, vec2 radii, bvec2 open, vec3 P, vec3 L) {
    vec3 axis = normalize(tip);
    return joint_light_path_in(joint_light_frame(n0, n1, tip, P, L), n0, n1, tip, radii, open, P,
                               P - axis * dot(axis, P), L);
}

// The side wall's part alone for a point q of the container's cross-section in unit space (radius 1): what
// the filtered scan takes per fiber, as it took the segment's own cylinder before (the root and tip are
// left to the single fiber's shading).
float joint_light_path_unit(LightFrame f, vec2 q) {
    return max(joint_light_wall(f, f.turn[0] * q.x + f.turn[1] * q.y, dot(q, q) - 1.0), 0.0);
}

#endif
