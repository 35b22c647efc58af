"""The shape of curved fibers: ellipsoid profile, twist, curl, frizz and noise (glsl/fibers/shape.glsl,
osl/fibers/shape.osl).

A fiber of rest centre c (layout.py) sits at E(v) R(tau(v)) c + curl(v) at guide parameter v: E scales the
container's cross-section (ellipsoid), tau turns each ring about the axis (twist), curl moves the fiber on
a small circle (helix) or across its ring (wave), and frizz and noise move each fiber its own way
(``frizz_offset``). The pattern codes are what the uniforms uTwistPattern /
uCurlPattern and the OSL parameters carry, and are injected into both as defines (``defines.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..params import Params
from .hash import CH_FRIZZ_AMP, CH_FRIZZ_DIR, CH_FRIZZ_FREQ, CH_FRIZZ_PHASE, CH_NOISE_PHASE, key_random, wiggle_key

#: shape.twist_pattern and shape.curl_pattern as the integers the shaders read
TWIST_PATTERNS = {"uniform": 0, "ramped": 1, "alternating": 2}
CURL_PATTERNS = {"helix": 0, "wave": 1}
TWIST_UNIFORM, TWIST_RAMPED, TWIST_ALTERNATING = TWIST_PATTERNS.values()
CURL_HELIX, CURL_WAVE = CURL_PATTERNS.values()


#: ring widths of displacement at shape.frizz = 1 and shape.noise = 1, before ``displacement_scale``
FRIZZ_WIDTH = 0.5
NOISE_WIDTH = 0.1
#: the most a fiber may move off its rest line, in ring widths: the curl's own limit (params.py), which
#: the curl, the frizz and the noise share, so a fiber keeps to its slot and every traversal bound holds
DISPLACEMENT_LIMIT = 0.5


def displacement_scale(curl: float, frizz: float, noise: float) -> float:
    """The factor on the curl, frizz and noise amplitudes (ring widths) that keeps their sum within
    DISPLACEMENT_LIMIT: 1 while it is (every look without frizz or noise), else they shrink together."""
    total = curl + FRIZZ_WIDTH * frizz + NOISE_WIDTH * noise
    return 1.0 if total <= DISPLACEMENT_LIMIT else DISPLACEMENT_LIMIT / total


def shape_amplitudes(p: Params) -> tuple[float, float, float]:
    """Unit-space (curl, frizz, noise) amplitudes, as every twin computes them (the renderer's uniforms,
    osl/stages/container.osl): ring widths times ``displacement_scale`` over the rings."""
    c, z, n = p["shape.curl_amplitude"], FRIZZ_WIDTH * p["shape.frizz"], NOISE_WIDTH * p["shape.noise"]
    k, rings = displacement_scale(c, p["shape.frizz"], p["shape.noise"]), p["fibers.rings"]
    return c * k / rings, z * k / rings, n * k / rings


@dataclass(frozen=True)
class Shape:
    ellipsoid: float
    twist: float
    twist_pattern: int
    curl_amplitude: float      # unit space
    curl_frequency: float
    curl_pattern: int
    frizz: float = 0.0              # shape.frizz: how far each fiber's frequency may stray
    frizz_amplitude: float = 0.0    # unit space: the most a fiber's frizz moves it
    noise_amplitude: float = 0.0    # unit space
    noise_frequency: float = 0.0

    @staticmethod
    def from_params(p: Params) -> Shape:
        curl, frizz, noise = shape_amplitudes(p)
        return Shape(p["shape.ellipsoid"], p["shape.twist"], TWIST_PATTERNS[p["shape.twist_pattern"]],
                     curl, p["shape.curl_frequency"], CURL_PATTERNS[p["shape.curl_pattern"]],
                     p["shape.frizz"], frizz, noise, p["shape.noise_frequency"])

    @property
    def frizzed(self) -> bool:
        return self.frizz_amplitude > 0 or self.noise_amplitude > 0

    @property
    def displacement(self) -> float:
        """The most a fiber's centre moves off its (scaled, twisted) rest line: the bands, the reach and
        the chord rule take this where they took the curl amplitude (curl + 0 + 0 is the curl exactly)."""
        return self.curl_amplitude + self.frizz_amplitude + self.noise_amplitude

    @property
    def frizz_frequency_max(self) -> float:
        return self.curl_frequency * (1.0 + 0.5 * self.frizz)

    @property
    def curved(self) -> bool:
        return self.ellipsoid > 0 or self.curl_amplitude > 0 or self.twist != 0 or self.frizzed


def shape_twist(sh: Shape, v, ring):
    """tau(v): how far ring ``ring`` has turned at guide parameter v."""
    t = v * v if sh.twist_pattern == TWIST_RAMPED else v
    sgn = np.where((sh.twist_pattern == TWIST_ALTERNATING) & (np.asarray(ring) % 2 == 1), -1.0, 1.0)
    return sgn * 2 * math.pi * sh.twist * t


def shape_scale(sh: Shape, v):
    """E(v): the ellipsoid's scale of the cross-section at guide parameter v (1 at the middle), v taken
    within the guide: a slab's wedge past a tilted root or tip cap reaches beyond [0, 1] (glsl/fibers/
    shape.glsl says why)."""
    x = sh.ellipsoid * (2.0 * np.clip(v, 0.0, 1.0) - 1.0)
    return np.sqrt(np.maximum(0.0, 1.0 - x * x))


def frizz_randoms(curl_phase):
    """A fiber's (amplitude, frequency, direction, phase, noise phase) numbers in [0, 1), from its curl
    phase (hash.py: wiggle_key)."""
    key = wiggle_key(curl_phase)
    return tuple(key_random(key, ch) for ch in (CH_FRIZZ_AMP, CH_FRIZZ_FREQ, CH_FRIZZ_DIR, CH_FRIZZ_PHASE,
                                                 CH_NOISE_PHASE))


def frizz_offset(sh: Shape, v, curl_phase):
    """The frizz and noise displacement of a fiber at guide parameter v, in its ring's frame (the frame that
    turns with the twist, where it is a fixed direction, as the wave's): the frizz sways a random amount
    (up to frizz_amplitude) along a random direction at the curl's frequency times 1 + frizz (u - 1/2);
    the noise, a fixed amplitude at noise_frequency, sways across it. Each with its own random phase."""
    ua, uf, ud, up, un = frizz_randoms(curl_phase)
    theta = 2 * math.pi * ud
    dx, dy = np.cos(theta), np.sin(theta)
    f = sh.curl_frequency * (1.0 + sh.frizz * (uf - 0.5))
    k = sh.frizz_amplitude * ua * np.sin(2 * math.pi * (f * v + up))
    m = sh.noise_amplitude * np.sin(2 * math.pi * (sh.noise_frequency * v + un))
    return k * dx - m * dy, k * dy + m * dx


def fiber_center_at(sh: Shape, rest_x, rest_y, v, ring, curl_phase):
    """Unit-space centre of a fiber of rest centre (rest_x, rest_y) at guide parameter v."""
    tau = shape_twist(sh, v, ring)
    ct, st = np.cos(tau), np.sin(tau)
    e = shape_scale(sh, v)
    cx, cy = e * (ct * rest_x - st * rest_y), e * (st * rest_x + ct * rest_y)
    if sh.curl_amplitude > 0:
        a = 2 * math.pi * (sh.curl_frequency * v + curl_phase)
        if sh.curl_pattern == CURL_HELIX:
            cx, cy = cx + sh.curl_amplitude * np.cos(a), cy + sh.curl_amplitude * np.sin(a)
        else:
            length = np.hypot(cx, cy)
            safe = np.where(length > 0, length, 1.0)
            ax, ay = np.where(length > 0, -cy / safe, 1.0), np.where(length > 0, cx / safe, 0.0)
            s = sh.curl_amplitude * np.sin(a)
            cx, cy = cx + s * ax, cy + s * ay
    if sh.frizzed:
        fx, fy = frizz_offset(sh, v, curl_phase)
        cx, cy = cx + ct * fx - st * fy, cy + st * fx + ct * fy
    return cx, cy
