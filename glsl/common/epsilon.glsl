// epsilon.glsl: every tolerance of the shaders, in one place, each named for what it protects.
// Angles are radians, lengths are in unit space (container radius = 1) unless said otherwise.
// Not here: the floors inside a shading formula (kajiya_kay.glsl's roughness, marschner.glsl's azimuth)
// and the viewer's heat-map scale (display.frag), which are parts of those formulas, not tolerances.
// Twin: osl/common/epsilon.osl (the same values, as VF_ macros).

#ifndef COMMON_EPSILON_GLSL
#define COMMON_EPSILON_GLSL

const float INF = 1e38;             // larger than any distance; finite so it is a legal constant
// Smallest divisor: a zero fiber radius or ray component divides to a large finite number, never inf/NaN.
const float EPS_DIVISOR = 1e-30;

// Slack added to a fiber's angular reach so float32 rounding of atan() never drops a candidate.
const float EPS_ANGLE = 2e-5;
// Relative slack of the bounding cylinder used before entering unit space.
const float EPS_BOUND = 1e-4;
// Smallest |cos| of a joint plane's tilt from the axis: a plane nearly along the axis leans at most
// 1e6 radii past its end point, so the bounding slab stays finite (container.glsl: joint_slope).
const float EPS_JOINT_COS = 1e-6;
// Slack that widens a ring's band (shaped.glsl: ring_band) so a fiber touching its edge stays inside.
const float EPS_BAND = 1e-6;
// Relative amount a chord's distance to the axis is taken nearer (shaped.glsl): rounding may only widen
// the reach it gives, never narrow it.
const float EPS_CHORD = 1e-5;
// Relative slack on exact mode's count of candidates past an improvement (shaped.glsl), so rounding of
// 2 reach / dphi never drops the last one.
const float EPS_AFTER = 1e-6;
// The most a fiber's rest chord may stray from its rest angle, in the frame turned by the twist
// interpolated along a chord piece, for the piece's window to use that frame (shaped.glsl: piece_window);
// renderer.py's loop bound adds twice it to each piece's window.
const float EPS_TURNED_CHORD = 0.08;
// Guide-parameter slack of the shaped traversal's length screen (shaped.glsl): a fiber is passed over
// on a chord piece only when it ends this much below the piece's lowest height, far more than the
// rounding between the piece's heights and piece_entry's length cut.
const float EPS_V_END = 1e-5;
// Step in guide parameter of the central difference that gives a curved fiber's dc/dv for shading.
const float DCDV_STEP = 1e-3;
// Relative margin on the walk's cut (walk.frag: walk_cut): a container whose bound the ray enters up to
// this much after the nearest hit is still visited, for the rounding between box and unit-space entry.
const float EPS_WALK_CUT = 1e-5;
// Relative margin past a hit known elsewhere (traverse.glsl: limit_traversal): a fiber hit up to this much
// behind it is still found, so a tie (a fiber crossing a joint, in both segments) is broken as before.
const float EPS_KNOWN = 1e-4;
// Relative rounding of a world t, in float32 units of |t| (32 ulp), that the known hit's margin adds at the
// container's scale: t - tb loses digits where a small container lies far away (harolongo: 51 units off,
// radii of hundredths), and a tie one ulp apart then fell outside EPS_KNOWN.
const float EPS_KNOWN_T = 4e-6;
// Where a traced shadow ray starts, in container radii along the light from the hit, so it leaves the
// fiber it starts on (fiber_shading.glsl).
const float EPS_SHADOW_START = 1e-3;
// A projected corner counts as behind the camera unless clip w exceeds this share of |clip xyz|
// (container.vert, coverage.vert).
const float EPS_CLIP_W = 1e-6;
// Smallest cos of the angle between the viewer's proxy's end plane and the axis: a plane nearly along
// the axis slides the proxy's rim at most 1e3 radii (viewer/proxy.vert).
const float EPS_PROXY_JOINT_COS = 1e-3;
// Squared xy length of a light direction in container space below which it runs along the axis: the
// density estimate then caps the path instead of dividing by 0 (light.glsl: density_transmittance).
const float EPS_LIGHT_AXIS2 = 1e-6;
// Squared length in pixels below which a proxy's screen-space axis has no direction (container.vert).
const float EPS_SCREEN_AXIS2 = 1e-12;

#endif
