// container.glsl: a container segment (hair cylinder) and the projective "unit space" inside it.
//   Segment  make_segment(vec4 a, vec4 b, vec4 c, vec4 d, vec4 e)      from the per-instance attributes
//   pack_segment(Segment, out vec4[7]) / Segment unpack_segment(vec4[7])   as flat varyings
//   bool     to_unit_space(Segment seg, vec3 ro, vec3 rd, float tNear, out UnitRay ur)
//   bool     clip_to_container(Segment seg, inout UnitRay ur)     [s0, s1] of a unit-space ray
//   float    unit_to_world_t(Segment seg, UnitRay ur, float s)
//   float    z_cut_unit(Segment seg, float vEnd)
//   float    unit_to_v(Segment seg, float zUnit)
// Unit space: P' = P_local / w(z), w(z) = r0 + kappa z. It maps the (tapered) container to the unit
// cylinder and every fiber to a vertical cylinder of radius fiber_radius; lines stay lines and order
// along a ray is kept while w > 0, so the nearest hit there is the nearest hit in the world.
// Twin: app/reference.py (segment, to_unit_space, unit_to_world_t, z_cut_unit).

#include "common/epsilon.glsl"
#include "geometry/intervals.glsl"

#ifndef GEOMETRY_CONTAINER_GLSL
#define GEOMETRY_CONTAINER_GLSL

struct Segment {
    vec3 p0;            // camera-relative
    vec3 ex, ey, ez;    // local frame, ez along the axis
    float h;            // axis length
    float r0;
    float kappa;        // dr/dz (taper)
    vec3 n0, n1;        // joint planes in the local frame
    float v0, v1;       // guide parameter (0 root .. 1 tip) at the ends
    uint guide;
    float zLo, zHi;     // bounding slab: joint planes lean past the end points
    float rBound;
};

struct UnitRay {
    float tb;           // world t of the unit-space origin
    vec3 o;             // local origin at tb
    vec3 d;             // local unit direction
    float wO;           // w(o.z)
    vec3 O;             // unit-space origin
    vec3 D;             // unit-space unit direction
    float Dlen;         // length of the direction before normalisation
    float s0, s1;       // inside the container
    float sKnown;       // a hit this far is known elsewhere: nothing past it matters (INF: none)
};

// How far a joint plane leans past the end point per unit of radius (tan of its tilt).
float joint_slope(vec3 n) {
    float c = abs(n.z);
    return sqrt(max(0.0, 1.0 - c * c)) / max(c, EPS_JOINT_COS);
}

Segment make_segment(vec4 a, vec4 b, vec4 c, vec4 d, vec4 e) {
    Segment s;
    s.p0 = a.xyz;
    vec3 axis = b.xyz - a.xyz;
    s.h = length(axis);
    s.ez = axis / s.h;
    s.ex = normalize(e.xyz - s.ez * dot(e.xyz, s.ez));
    s.ey = cross(s.ez, s.ex);
    mat3 localFromWorld = transpose(mat3(s.ex, s.ey, s.ez));
    s.n0 = localFromWorld * c.xyz;
    s.n1 = localFromWorld * d.xyz;
    s.r0 = a.w;
    s.kappa = (b.w - a.w) / s.h;
    s.v0 = c.w;
    s.v1 = d.w;
    s.guide = uint(e.w);
    s.rBound = max(a.w, b.w);
    s.zLo = -s.rBound * joint_slope(s.n0);
    s.zHi = s.h + s.rBound * joint_slope(s.n1);
    return s;
}

// A segment as seven vec4s, so container.vert builds it once per vertex and the fragment shader only
// unpacks it (flat varyings): p0 h | ex r0 | ey kappa | ez v0 | n0 v1 | n1 guide | zLo zHi rBound -.
void pack_segment(Segment s, out vec4 q[7]) {
    q[0] = vec4(s.p0, s.h);
    q[1] = vec4(s.ex, s.r0);
    q[2] = vec4(s.ey, s.kappa);
    q[3] = vec4(s.ez, s.v0);
    q[4] = vec4(s.n0, s.v1);
    q[5] = vec4(s.n1, uintBitsToFloat(s.guide));
    q[6] = vec4(s.zLo, s.zHi, s.rBound, 0.0);
}

Segment unpack_segment(vec4 q[7]) {
    Segment s;
    s.p0 = q[0].xyz;
    s.h = q[0].w;
    s.ex = q[1].xyz;
    s.r0 = q[1].w;
    s.ey = q[2].xyz;
    s.kappa = q[2].w;
    s.ez = q[3].xyz;
    s.v0 = q[3].w;
    s.n0 = q[4].xyz;
    s.v1 = q[4].w;
    s.n1 = q[5].xyz;
    s.guide = floatBitsToUint(q[5].w);
    s.zLo = q[6].x;
    s.zHi = q[6].y;
    s.rBound = q[6].z;
    return s;
}

// Clip [s0, s1] to the half-space m . P <= c.
void clip_half_space(vec3 O, vec3 D, vec3 m, float c, inout float s0, inout float s1) {
    float mo = dot(O, m) - c;
    float md = dot(D, m);
    float tp = -mo / md;                        // unused where md == 0 (parallel: all or nothing)
    s0 = md < 0.0 ? max(s0, tp) : s0;
    s1 = md > 0.0 ? min(s1, tp) : (md == 0.0 && mo > 0.0 ? -INF : s1);
}

bool clip_to_container(Segment seg, inout UnitRay ur);

// On a miss ur stays finite with an empty [s0, s1] (s0 = INF), so callers may go on without a branch.
bool to_unit_space(Segment seg, vec3 ro, vec3 rd, float tNear, out UnitRay ur) {
    mat3 localFromWorld = transpose(mat3(seg.ex, seg.ey, seg.ez));
    vec3 o = localFromWorld * (ro - seg.p0);
    vec3 d = localFromWorld * rd;
    // Bounding cylinder and slab first: cheap, conservative, and a region where w(z) > 0. Moving the
    // origin to its entry keeps every later solve near the primitive (small numbers, no cancellation).
    vec2 c = circle_interval(o.xy, d.xy, vec2(0.0), seg.rBound * (1.0 + EPS_BOUND));
    vec2 z = slab(o.z, d.z, seg.zLo, seg.zHi);
    float tb0 = max(max(c.x, z.x), tNear);
    float tb1 = min(c.y, z.y);
    bool bounded = tb0 <= tb1;
    ur.tb = bounded ? tb0 : tNear;
    ur.o = bounded ? o + tb0 * d : vec3(0.0);
    ur.d = d;
    ur.wO = seg.r0 + seg.kappa * ur.o.z;
    ur.O = ur.o / ur.wO;
    vec3 D = d * ur.wO - ur.o * (seg.kappa * d.z);
    ur.Dlen = length(D);
    ur.D = D / ur.Dlen;
    bool inside = clip_to_container(seg, ur) && bounded;
    ur.s0 = inside ? ur.s0 : INF;
    ur.s1 = inside ? ur.s1 : -INF;
    ur.sKnown = INF;
    return inside;
}

// The stretch [s0, s1] (s >= 0) of the unit-space ray O + s D inside the container: unit cylinder,
// root-side joint plane, tip-side joint plane (planes stay planes under the projective map).
bool clip_to_container(Segment seg, inout UnitRay ur) {
    vec2 cyl = circle_interval(ur.O.xy, ur.D.xy, vec2(0.0), 1.0);
    ur.s0 = max(cyl.x, 0.0);
    ur.s1 = cyl.y;
    clip_half_space(ur.O, ur.D, -seg.r0 * seg.n0, 0.0, ur.s0, ur.s1);
    clip_half_space(ur.O, ur.D, seg.r0 * seg.n1 + vec3(0.0, 0.0, seg.n1.z * seg.h * seg.kappa),
                    seg.n1.z * seg.h, ur.s0, ur.s1);
    return ur.s0 <= ur.s1;
}

float unit_to_world_t(Segment seg, UnitRay ur, float s) {
    float sigma = s / ur.Dlen;
    return ur.tb + sigma * ur.wO * ur.wO / (1.0 - sigma * ur.wO * seg.kappa * ur.d.z);
}

// unit_to_world_t inverted: the unit-space s of world t along the ray, negative before the unit-space
// origin; INF where the taper's w(z) has fallen to 0 on the way (t lies past the whole container).
float world_to_unit_s(Segment seg, UnitRay ur, float t) {
    float u = t - ur.tb;
    float w = ur.wO + u * seg.kappa * ur.d.z;
    return w > 0.0 ? u / (ur.wO * w) * ur.Dlen : INF;
}

// Guide parameter v at unit-space height zUnit (the projective map inverted along the axis).
float unit_to_v(Segment seg, float zUnit) {
    float z = seg.r0 * zUnit / (1.0 - seg.kappa * zUnit);
    return seg.v0 + (seg.v1 - seg.v0) * z / seg.h;
}

float z_cut_unit(Segment seg, float vEnd) {
    if (vEnd >= seg.v1) return INF;
    if (vEnd <= seg.v0) return -INF;
    float z = (vEnd - seg.v0) / (seg.v1 - seg.v0) * seg.h;
    return z / (seg.r0 + seg.kappa * z);
}

#endif
