// tangent.glsl: the direction a bent guide is shaded with.
//   vec3 joint_blended_axis(vec3 n0, vec3 n1, float h, vec3 Pl)   at a point of the segment's local frame
//   vec3 joint_blend(vec3 n0, vec3 n1, float d0, float d1)       given the point's distances from the planes
//   vec3 turn_with(vec3 v, vec3 a, vec3 b)     v turned by the smallest rotation taking unit a to unit b
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

#ifndef SHADING_TANGENT_GLSL
#define SHADING_TANGENT_GLSL

// d0, d1: the point's distance from the root plane and from the tip plane (both >= 0 inside the segment)
vec3 joint_blend(vec3 n0, vec3 n1, float d0, float d1) {
    d0 = max(d0, 0.0);
    d1 = max(d1, 0.0);
    float u = d0 + d1 > 0.0 ? d0 / (d0 + d1) : 0.5;
    return normalize(mix(n0, n1, u));
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

#endif
