"""Per-fiber random numbers: the one hash every twin uses (glsl/common/hash.glsl, osl/common/hash.osl).

A fiber's numbers depend only on integers (seed, guide, ring, fiber, channel), so they never change with
the camera or with float rounding, and numpy, GLSL and OSL agree bit for bit. ``thesis_random`` is the
thesis's float LCG, kept for fidelity to the thesis and measured against it.
"""

from __future__ import annotations

import numpy as np

#: random-number channels: one independent number per purpose and fiber (injected into GLSL as CH_*,
#: into OSL as VF_CH_*); CH_RING draws each ring's rotation, on the CPU and in the OSL export
#: the CH_FRIZZ_* and CH_NOISE_PHASE channels are drawn from the fiber's curl phase (``wiggle_key``), not
#: from its fiber key, so every twin that holds the phase holds the frizz too (app/fibers/shape.py)
CHANNELS = {"CH_RADIAL": 0, "CH_ANGULAR": 1, "CH_LENGTH": 2, "CH_TINT": 3, "CH_ROUGH": 4, "CH_CURL": 5,
            "CH_RING": 6, "CH_FRIZZ_AMP": 7, "CH_FRIZZ_FREQ": 8, "CH_FRIZZ_DIR": 9, "CH_FRIZZ_PHASE": 10,
            "CH_NOISE_PHASE": 11}
(CH_RADIAL, CH_ANGULAR, CH_LENGTH, CH_TINT, CH_ROUGH, CH_CURL, CH_RING, CH_FRIZZ_AMP, CH_FRIZZ_FREQ,
 CH_FRIZZ_DIR, CH_FRIZZ_PHASE, CH_NOISE_PHASE) = CHANNELS.values()
SEED_OFFSET = 0x9E3779B9   # the golden-ratio constant added to the seed before the first round
THESIS_LCG = 1207.523      # thesis expression 3.4


def lowbias32(x):
    """Chris Wellons' lowbias32 integer hash, on uint32 arrays (wrapping arithmetic as in GLSL)."""
    x = np.asarray(x, dtype=np.uint32).copy()
    with np.errstate(over="ignore"):
        x ^= x >> np.uint32(16)
        x *= np.uint32(0x7FEB352D)
        x ^= x >> np.uint32(15)
        x *= np.uint32(0x846CA68B)
        x ^= x >> np.uint32(16)
    return x


def ring_key(seed: int, guide, ring) -> np.ndarray:
    """The part of ``fiber_key`` shared by one ring's fibers (the GLSL computes it once per arc)."""
    with np.errstate(over="ignore"):
        h = lowbias32(np.uint32(seed) + np.uint32(SEED_OFFSET))
    h = lowbias32(h ^ np.asarray(guide).astype(np.uint32))
    return lowbias32(h ^ np.asarray(ring).astype(np.uint32))


def fiber_key(seed: int, guide, ring, fiber) -> np.ndarray:
    """Hash of (seed, guide, ring, fiber), once per fiber; each channel costs one round more
    (``key_random``). ``fiber_random(s, g, r, f, ch) == key_random(fiber_key(s, g, r, f), ch)``."""
    return lowbias32(ring_key(seed, guide, ring) ^ np.asarray(fiber).astype(np.uint32))


def key_random(key, channel) -> np.ndarray:
    """Uniform in [0, 1): 24 bits, exactly representable in float32 so GLSL and numpy agree bit for bit."""
    bits = lowbias32(np.asarray(key, np.uint32) ^ np.asarray(channel).astype(np.uint32)) >> np.uint32(8)
    return bits.astype(np.float64) / 16777216.0


def key_randoms(key):
    """The three numbers that place a fiber: radial, angular, length."""
    return tuple(key_random(key, ch) for ch in (CH_RADIAL, CH_ANGULAR, CH_LENGTH))


def fiber_hash(seed, guide, ring, fiber, channel) -> np.ndarray:
    """The 32-bit hash behind ``fiber_random``: ``fiber_key`` then one round for the channel."""
    return lowbias32(fiber_key(seed, guide, ring, fiber) ^ np.asarray(channel).astype(np.uint32))


def fiber_random(seed, guide, ring, fiber, channel) -> np.ndarray:
    """Uniform in [0, 1) per (seed, guide, ring, fiber, channel)."""
    return (fiber_hash(seed, guide, ring, fiber, channel) >> np.uint32(8)).astype(np.float64) / 16777216.0


def wiggle_key(curl_phase) -> np.ndarray:
    """The key of a fiber's frizz and noise numbers: its curl phase's bits. The phase is k / 2^24 for the
    integer hash and a float32 for the thesis's, so phase * 2^24 is exact in float32 and truncates alike
    in numpy, GLSL and OSL; the phase's 24 bits stand for the fiber as well as its key would."""
    return (np.asarray(curl_phase, np.float64) * 16777216.0).astype(np.uint32)


def thesis_random(slot_deg, ring, channel, dtype=np.float32):
    """The thesis's LCG, fract(1207.523 * phi), phi the fiber's angular position in degrees.

    Extended to several channels and rings by small offsets of phi. Evaluated in ``dtype``: float32 is what
    a shader computes (and the source of its instability), float64 the ideal.
    """
    x = (np.asarray(slot_deg, dtype) + dtype(0.37) * np.asarray(channel, dtype)
         + dtype(0.11) * np.asarray(ring, dtype))
    y = dtype(THESIS_LCG) * x
    return (y - np.floor(y)).astype(np.float64)
