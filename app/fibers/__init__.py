"""The fiber model, owned once: where virtual fibers sit, their random numbers, their shape, its limits.

Every twin takes its numbers from here: the GLSL (glsl/fibers/layout.glsl, glsl/common/hash.glsl,
glsl/fibers/shape.glsl) through the defines of ``defines.py`` and the uniforms the renderer fills from
``ring_layout``; the OSL export (osl/) through the same defines; the explicit baseline
(app/render/explicit.py), which stores the same fibers; and the float64 reference (app/reference.py), which
judges the shader and imports the model from here. The renderer imports the model, never the reference.
docs/architecture.md lists every GLSL function of the model with its numpy and OSL twins.

Modules: ``layout`` (rings, fiber counts, placement), ``hash`` (lowbias32, fiber keys and randoms,
channels), ``shape`` (Shape, twist and curl codes), ``taper`` (each fiber's width toward its own tip),
``limits`` (MAX_RINGS, MAX_SUB), ``defines`` (all of these as GLSL/OSL defines).
"""

from __future__ import annotations

from .defines import glsl_defines, osl_defines, osl_header
from .hash import (CH_ANGULAR, CH_CURL, CH_FRIZZ_AMP, CH_FRIZZ_DIR, CH_FRIZZ_FREQ, CH_FRIZZ_PHASE, CH_LENGTH,
                   CH_NOISE_PHASE, CH_RADIAL, CH_RING, CH_ROUGH, CH_TINT, CHANNELS, SEED_OFFSET, THESIS_LCG,
                   fiber_hash, fiber_key, fiber_random, key_random, key_randoms, lowbias32, ring_key, thesis_random,
                   wiggle_key)
from .layout import (LAYOUT_KEYS, RingLayout, all_fibers, fiber_center, fiber_count, fiber_randoms, ring_layout,
                     ring_step_deg)
from .limits import MAX_RINGS, MAX_SUB
from .shape import (CURL_HELIX, CURL_PATTERNS, CURL_WAVE, DISPLACEMENT_LIMIT, FRIZZ_WIDTH, NOISE_WIDTH,
                    TWIST_ALTERNATING, TWIST_PATTERNS, TWIST_RAMPED, TWIST_UNIFORM, Shape, displacement_scale,
                    fiber_center_at, frizz_offset, frizz_randoms, shape_amplitudes, shape_scale, shape_twist)
from .taper import TAPER_KEYS, Taper, taper_apex, taper_line, tapered

__all__ = [
    "MAX_RINGS", "MAX_SUB",
    "CHANNELS", "CH_RADIAL", "CH_ANGULAR", "CH_LENGTH", "CH_TINT", "CH_ROUGH", "CH_CURL", "CH_RING",
    "CH_FRIZZ_AMP", "CH_FRIZZ_FREQ", "CH_FRIZZ_DIR", "CH_FRIZZ_PHASE", "CH_NOISE_PHASE", "wiggle_key",
    "SEED_OFFSET", "THESIS_LCG", "lowbias32", "ring_key", "fiber_key", "key_random", "key_randoms",
    "fiber_hash", "fiber_random", "thesis_random",
    "LAYOUT_KEYS", "RingLayout", "ring_layout", "ring_step_deg", "fiber_count", "fiber_randoms",
    "fiber_center", "all_fibers",
    "TWIST_PATTERNS", "CURL_PATTERNS", "TWIST_UNIFORM", "TWIST_RAMPED", "TWIST_ALTERNATING", "CURL_HELIX",
    "CURL_WAVE", "Shape", "shape_twist", "shape_scale", "fiber_center_at",
    "TAPER_KEYS", "Taper", "taper_line", "taper_apex", "tapered",
    "FRIZZ_WIDTH", "NOISE_WIDTH", "DISPLACEMENT_LIMIT", "displacement_scale", "shape_amplitudes",
    "frizz_randoms", "frizz_offset",
    "glsl_defines", "osl_defines", "osl_header",
]
