// palette.glsl: colours for the viewer's debug views, the GLSL twin of app/render/debug_views.py
// (the command line's --output pictures), so the viewer and the CLI show the same colours.
//   vec3 id_color(uvec3 id)            fiber_id_image: (guide + 1, ring, fiber) hashed; 60..255 per channel
//   vec3 heat_color(float x)           heat(): x in [0, 1] on the 6-stop ramp (dark blue .. yellow .. red)
//   vec3 as_uint8(vec3 c)              floor to 8 bits, as numpy's astype(uint8) truncates
// Outputs are display values (written to an 8-bit target without conversion).

#include "common/hash.glsl"

#ifndef VIEWER_PALETTE_GLSL
#define VIEWER_PALETTE_GLSL

vec3 as_uint8(vec3 c) {
    return floor(clamp(c, 0.0, 1.0) * 255.0) / 255.0;
}

vec3 id_color(uvec3 id) {
    uint key = lowbias32(id.x * 73856093u ^ lowbias32(id.y * 19349663u ^ id.z)) | 1u;
    uint h = lowbias32(key);
    vec3 byte = vec3(float(h & 0xffu), float((h >> 8) & 0xffu), float((h >> 16) & 0xffu));
    return floor(60.0 + byte * (195.0 / 255.0)) / 255.0;
}

const vec3 HEAT_STOPS[6] = vec3[6](
    vec3(0.05, 0.03, 0.25), vec3(0.1, 0.3, 0.6), vec3(0.1, 0.6, 0.6), vec3(0.5, 0.8, 0.3),
    vec3(0.98, 0.85, 0.2), vec3(0.9, 0.2, 0.1));

vec3 heat_color(float x) {
    float s = clamp(x, 0.0, 1.0) * 5.0;
    int i = min(int(s), 4);
    return as_uint8(mix(HEAT_STOPS[i], HEAT_STOPS[i + 1], s - float(i)));
}

#endif
