"""The shape of curved fibers: ellipsoid profile, twist and curl (glsl/fibers/shape.glsl, osl/fibers/shape.osl).

A fiber of rest centre c (layout.py) sits at E(v) R(tau(v)) c + curl(v) at guide parameter v: E scales the
container's cross-section (ellipsoid), tau turns each ring about the axis (twist), curl moves the fiber on
a small circle (helix) or across its ring (wave). The pattern codes are what the uniforms uTwistPattern /
uCurlPattern and the OSL parameters carry, and are injected into both as defines (``defines.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..params import Params

#: shape.twist_pattern and shape.curl_pattern as the integers the shaders read
TWIST_PATTERNS = {"uniform": 0, "ramped": 1, "alternating": 2}
CURL_PATTERNS = {"helix": 0, "wave": 1}
TWIST_UNIFORM, TWIST_RAMPED, TWIST_ALTERNATING = TWIST_PATTERNS.values()
CURL_HELIX, CURL_WAVE = CURL_PATTERNS.values()


@dataclass(frozen=True)
class Shape:
    ellipsoid: float
    twist: float
    twist_pattern: int
    curl_amplitude: float      # unit space
    curl_frequency: float
    curl_pattern: int

    @staticmethod
    def from_params(p: Params) -> "Shape":
        return Shape(p["shape.ellipsoid"], p["shape.twist"], TWIST_PATTERNS[p["shape.twist_pattern"]],
                     p["shape.curl_amplitude"] / p["fibers.rings"], p["shape.curl_frequency"],
                     CURL_PATTERNS[p["shape.curl_pattern"]])

    @property
    def curved(self) -> bool:
        return self.ellipsoid > 0 or self.curl_amplitude > 0 or self.twist != 0


def shape_twist(sh: Shape, v, ring):
    """tau(v): how far ring ``ring`` has turned at guide parameter v."""
    t = v * v if sh.twist_pattern == TWIST_RAMPED else v
    sgn = np.where((sh.twist_pattern == TWIST_ALTERNATING) & (np.asarray(ring) % 2 == 1), -1.0, 1.0)
    return sgn * 2 * math.pi * sh.twist * t


def shape_scale(sh: Shape, v):
    """E(v): the ellipsoid's scale of the cross-section at guide parameter v (1 at the middle)."""
    x = sh.ellipsoid * (2.0 * np.asarray(v) - 1.0)
    return np.sqrt(np.maximum(0.0, 1.0 - x * x))


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
    return cx, cy
