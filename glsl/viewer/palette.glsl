// palette.glsl: colours for the viewer's debug views.
//   vec3 id_color(uvec3 id)        a stable, well-spread colour per (guide + 1, ring, fiber)
//   vec3 heat_color(float x)       x in [0, 1] -> 9-stop viridis, linearly interpolated
// Twin: app/viewer/display.py (HEAT_STOPS, heat_color) draws the legend from the same stops.

uint palette_hash(uint x) {           // Chris Wellons' lowbias32
    x ^= x >> 16;
    x *= 0x7feb352du;
    x ^= x >> 15;
    x *= 0x846ca68bu;
    x ^= x >> 16;
    return x;
}

vec3 hsv_to_rgb(vec3 c) {
    vec3 k = clamp(abs(fract(c.x + vec3(0.0, 2.0, 1.0) / 3.0) * 6.0 - 3.0) - 1.0, 0.0, 1.0);
    return c.z * mix(vec3(1.0), k, c.y);
}

vec3 id_color(uvec3 id) {
    uint h = palette_hash(palette_hash(palette_hash(id.x) ^ id.y) ^ id.z);
    float hue = float(h & 0xffffu) / 65535.0;
    float sat = 0.55 + 0.4 * float((h >> 16) & 0xffu) / 255.0;
    float val = 0.6 + 0.4 * float(h >> 24) / 255.0;
    return hsv_to_rgb(vec3(hue, sat, val));
}

const vec3 HEAT_STOPS[9] = vec3[9](
    vec3(0.267, 0.005, 0.329), vec3(0.283, 0.141, 0.458), vec3(0.254, 0.265, 0.530),
    vec3(0.207, 0.372, 0.553), vec3(0.164, 0.471, 0.558), vec3(0.128, 0.567, 0.551),
    vec3(0.135, 0.659, 0.518), vec3(0.478, 0.821, 0.318), vec3(0.993, 0.906, 0.144));

vec3 heat_color(float x) {
    float s = clamp(x, 0.0, 1.0) * 8.0;
    int i = min(int(s), 7);
    return mix(HEAT_STOPS[i], HEAT_STOPS[i + 1], s - float(i));
}
