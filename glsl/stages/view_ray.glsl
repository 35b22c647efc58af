// view_ray.glsl: the camera ray through a pixel, camera at the origin (positions are camera-relative).
//   vec3 view_ray(vec2 offset)                 offset: sub-pixel, in pixels about the pixel centre
//   vec3 view_ray_at(vec2 frag, vec2 offset)   the same through another pixel (its centre's window position)

#ifndef STAGES_VIEW_RAY_GLSL
#define STAGES_VIEW_RAY_GLSL

uniform vec3 uCamRight;         // world-space camera basis, scaled by tan(fov/2) (and aspect)
uniform vec3 uCamUp;
uniform vec3 uCamForward;
uniform vec2 uViewport;
uniform vec2 uPixelOffset;      // sub-pixel offset of the ray (antialiasing, stability tests)
uniform float uNear;

// ... through the pixel whose centre is at window position `frag` (a pass that runs over a list of
// pixels, walk.frag, casts the ray of the listed one, bit for bit the ray its own fragment would cast)
vec3 view_ray_at(vec2 frag, vec2 offset) {
    vec2 ndc = (frag + offset) / uViewport * 2.0 - 1.0;
    return normalize(uCamForward + ndc.x * uCamRight + ndc.y * uCamUp);
}

vec3 view_ray(vec2 offset) {
    return view_ray_at(gl_FragCoord.xy, offset);
}

#endif
