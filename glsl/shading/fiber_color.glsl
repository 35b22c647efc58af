// fiber_color.glsl: a fiber's albedo along its strand (root-to-tip gradient, the groom file's colours,
// the random tint).
//   float tip_weight(float v, float blend, float start)     how much tip colour at guide parameter v
//   vec3  fiber_color(uint guide, float v, float tint)      linear albedo of a fiber of that guide
// v runs from 0 at the root to 1 at the tip; tint is the fiber's key_random(CH_TINT) - 0.5.
// Per-guide colours (the groom file's, look.color_source = file) come as two vec4 per guide in
// GuideColors (root rgb, tip rgb), the scene's only colour data: nothing is stored per fiber.
// Twin: app/render/look.py (tip_weight, fiber_color); OSL: osl/shading/fiber_color.osl.
#ifndef SHADING_FIBER_COLOR_GLSL
#define SHADING_FIBER_COLOR_GLSL

uniform vec3 uBaseColor;        // linear; from RGB or from melanin (app/render/look.py)
uniform vec3 uTipColor;         // linear; look.tip_color, or from look.tip_melanin
uniform float uTipBlend;        // look.tip_blend: 0 = no gradient
uniform float uTipStart;        // look.tip_start
uniform float uTintVariation;
uniform int uGuideColors;       // 1: GuideColors holds the file's colours, 0: the look's colour only

layout(std430, binding = 4) readonly buffer GuideColors { vec4 guideColors[]; };   // two per guide

// The floor 1e-4 is part of the formula, not a tolerance: a blend that starts at the tip has no span.
float tip_weight(float v, float blend, float start) {
    float t = clamp((v - start) / max(1.0 - start, 1e-4), 0.0, 1.0);
    return blend * t * t * (3.0 - 2.0 * t);
}

vec3 fiber_color(uint guide, float v, float tint) {
    vec3 base = uBaseColor;
    if (uGuideColors != 0) {
        // the file's colours replace the look's, linearly from the guide's root to its tip
        vec3 root = guideColors[2u * guide].rgb;
        vec3 tip = guideColors[2u * guide + 1u].rgb;
        base = root + (tip - root) * clamp(v, 0.0, 1.0);
    }
    // written as base + (tip - base) w, not mix(): with no gradient (w = 0) the colour stays bit for bit
    base = base + (uTipColor - base) * tip_weight(v, uTipBlend, uTipStart);
    return clamp(base * (1.0 + uTintVariation * 2.0 * tint), 0.0, 1.0);
}

#endif
