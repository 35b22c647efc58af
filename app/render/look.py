"""Colour parameters to shader inputs: the look's base colour, including Cycles' melanin model.

The melanin conversion is the one of Blender Cycles' Principled Hair BSDF (melanin amount and redness to
eumelanin and pheomelanin concentrations, to an absorption coefficient), so a look tuned here exports to
the same hair closure in OSL. The preview needs a colour: the reflectance Cycles would associate with
that absorption, inverting its ``sigma_from_reflectance`` at the default radial roughness.
"""

from __future__ import annotations

import math

import numpy as np

from ..params import Params

EUMELANIN_SIGMA = np.array([0.506, 0.841, 1.653])
PHEOMELANIN_SIGMA = np.array([0.343, 0.733, 1.924])
RADIAL_ROUGHNESS = 0.3          # Cycles' default for the Principled Hair BSDF


def melanin_to_sigma(melanin: float, redness: float) -> np.ndarray:
    """Absorption coefficient (per unit fiber diameter) from melanin amount and redness."""
    quantity = -math.log(max(1.0 - melanin, 1e-4))
    return quantity * ((1.0 - redness) * EUMELANIN_SIGMA + redness * PHEOMELANIN_SIGMA)


def roughness_factor(radial_roughness: float) -> float:
    x = radial_roughness
    return (((((0.245 * x) + 5.574) * x - 10.73) * x + 2.532) * x - 0.215) * x + 5.969


def sigma_to_color(sigma: np.ndarray, radial_roughness: float = RADIAL_ROUGHNESS) -> np.ndarray:
    """Inverse of Cycles' sigma_from_reflectance: sigma = (log(c) / factor)^2."""
    return np.exp(-np.sqrt(np.maximum(sigma, 0.0)) * roughness_factor(radial_roughness))


def base_color(p: Params) -> tuple[float, float, float]:
    if p["look.color_mode"] == "melanin":
        c = sigma_to_color(melanin_to_sigma(p["look.melanin"], p["look.melanin_redness"]))
        return tuple(float(v) for v in c)
    return tuple(float(v) for v in p["look.color"])


def fiber_density(p: Params, fibers_per_container: int) -> float:
    """Fiber cross-section met per unit length of a light path in unit space (container radius 1):
    fibers per unit area times fiber diameter. Drives the density self-shadow estimate."""
    return fibers_per_container / math.pi * 2.0 * p["fibers.fiber_radius"]
