"""Where virtual fibers sit inside a container (thesis 3.3-3.8, 4.1, 4.3): the ring layout.

Ring i (0 = outermost) of K is the annulus [1 - (i+1)/K, 1 - i/K] of unit space (the container mapped to
the unit cylinder). Its n_i fibers sit at angles rot_i + j dphi_i, pushed by a radial and an angular offset
bounded per ring so that a fiber never leaves its slot; v_end is where along the guide (0 root .. 1 tip)
the fiber stops. The per-ring numbers are computed here once per parameter set, in float64, and reach the
GLSL as uniforms (app/render/renderer.py: ring_uniforms); the OSL export computes them in the shader
(osl/fibers/layout.osl: vf_ring), so that its sliders stay live.
GLSL twin: glsl/fibers/layout.glsl; OSL twin: osl/fibers/layout.osl.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..params import Params
from .hash import CH_ANGULAR, CH_LENGTH, CH_RADIAL, CH_RING, fiber_random, thesis_random


@dataclass(frozen=True)
class RingLayout:
    rings: int
    rho: np.ndarray        # ring centre radius, unit space
    n: np.ndarray          # fibers on the ring (int64)
    dphi: np.ndarray       # angular slot width, radians
    rot: np.ndarray        # ring rotation, radians
    max_dr: np.ndarray     # largest radial offset actually used (jitter already applied)
    max_dphi: np.ndarray   # largest angular offset actually used
    reach: np.ndarray      # angular reach of a fiber about its slot angle: max_dphi + disc half-angle
    ring_radius: np.ndarray  # fiber radius on each ring (the clump profile's edge_thickness; unit space)
    fiber_radius: float    # the core's, the largest of ring_radius: what bounds a traversal's windows
    length_jitter: float
    thesis_hash: bool
    seed: int

    @property
    def first(self) -> np.ndarray:
        """Index of each ring's first fiber in the container's flat fiber numbering."""
        return np.concatenate([[0], np.cumsum(self.n)[:-1]])

    @property
    def fibers_per_container(self) -> int:
        return int(self.n.sum())


# The parameters ring_layout reads: a frame asks for the layout several times (uniforms, loop budget), so
# it is computed once per distinct set and shared, its arrays read-only.
LAYOUT_KEYS = ("fibers.rings", "fibers.phi_step", "fibers.phi_increment", "fibers.even_spacing", "fibers.hash",
               "fibers.seed", "fibers.fiber_radius", "fibers.radial_jitter", "fibers.angular_jitter",
               "fibers.length_jitter", "fibers.edge_density", "fibers.edge_width", "fibers.edge_thickness")


def ring_layout(p: Params) -> RingLayout:
    return _ring_layout(tuple(p[k] for k in LAYOUT_KEYS))


@lru_cache(maxsize=64)
def _ring_layout(values: tuple) -> RingLayout:
    p = dict(zip(LAYOUT_KEYS, values))
    lay = _compute_ring_layout(p)
    for arr in (lay.rho, lay.n, lay.dphi, lay.rot, lay.max_dr, lay.max_dphi, lay.reach, lay.ring_radius):
        arr.setflags(write=False)
    return lay


def edge_ramp(p, rings: int) -> np.ndarray:
    """Per ring, how far the clump profile has come: 1 on the outermost ring, 0 on every ring whose outer
    boundary 1 - i/K lies edge_width or more inside the edge, linear between."""
    # (1 - outer) / width from the ring index, so the outermost ring's ramp is exactly 1 (and the OSL's,
    # which computes the same in float32: osl/fibers/layout.osl: vf_ring)
    inset = np.arange(rings, dtype=np.float64) / rings
    return np.clip(1.0 - inset / p["fibers.edge_width"], 0.0, 1.0)


def edge_profile(p, rho: np.ndarray) -> np.ndarray:
    """Per ring, the clump profile's density factor (1 in the core, edge_density on the outermost ring).

    It falls linearly with the ring's outer boundary 1 - i/K over the outer edge_width of the radius, so
    the outermost ring (boundary 1) gets edge_density exactly and a ring whose boundary is 1 - edge_width
    or less gets 1. With the default edge_density 1 every factor is exactly 1.0 (today's layout)."""
    return 1.0 - (1.0 - p["fibers.edge_density"]) * edge_ramp(p, len(rho))


def ring_step_deg(p, rho: np.ndarray) -> np.ndarray:
    """Per ring, the angular step between fibers in degrees: phi_step grown by phi_increment per ring, by
    even_spacing towards the axis (1 keeps the arc length between neighbours equal on every ring) and by
    the clump profile towards the edge (a ring at density factor f has 1/f of the step, f of the fibers)."""
    i = np.arange(len(rho), dtype=np.float64)
    return (p["fibers.phi_step"] + i * p["fibers.phi_increment"]) * (
        1.0 + p["fibers.even_spacing"] * (rho[0] / rho - 1.0)) / edge_profile(p, rho)


def _compute_ring_layout(p: dict) -> RingLayout:
    K = p["fibers.rings"]
    i = np.arange(K, dtype=np.float64)
    rho = 1.0 - (i + 0.5) / K
    half_width = 0.5 / K
    step_deg = ring_step_deg(p, rho)
    n = np.maximum(1, np.floor(360.0 / step_deg + 0.5)).astype(np.int64)
    dphi = 2.0 * math.pi / n
    thesis = p["fibers.hash"] == "thesis"
    seed = p["fibers.seed"]
    rot = np.zeros(K) if thesis else fiber_random(seed, 0, np.arange(K), 0, CH_RING) * dphi
    rf = p["fibers.fiber_radius"]
    # the clump profile thins the outer rings' fibers as it thins their number (1.0 exactly by default)
    ring_rf = rf * (1.0 - (1.0 - p["fibers.edge_thickness"]) * edge_ramp(p, K))
    max_dr = np.maximum(0.0, half_width - ring_rf) * p["fibers.radial_jitter"]
    rho_min = rho - max_dr
    # half the angle a fiber's disc covers seen from the axis; a disc that reaches the axis covers half the
    # turn. rho_min is 0 on the innermost ring at full radial jitter: rf / 0 would be nan for rf = 0
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(rho_min > ring_rf, ring_rf / rho_min, 1.0) if rf > 0 else np.zeros(K)
    disc_half_angle = np.arcsin(ratio)
    max_dphi = np.maximum(0.0, 0.5 * dphi - disc_half_angle) * p["fibers.angular_jitter"]
    return RingLayout(K, rho, n, dphi, rot, max_dr, max_dphi, max_dphi + disc_half_angle, ring_rf, rf,
                      p["fibers.length_jitter"], thesis, seed)


def fiber_count(p: Params, n_containers: int = 1) -> tuple[float, int]:
    """(thesis Expression 4.1, exact count) for ``n_containers`` containers.

    Expression 4.1 sums 360/phi_step over the rings; the exact count is what is drawn, since a ring holds a
    whole number of fibers (360/phi_step rounded to the nearest integer).
    """
    lay = ring_layout(p)
    step = ring_step_deg(p, lay.rho)
    return float((360.0 / step).sum() * n_containers), int(lay.n.sum()) * n_containers


def fiber_randoms(lay: RingLayout, guide, ring, j, channel):
    """Per-fiber random number from the selected hash."""
    if lay.thesis_hash:
        slot_deg = np.degrees(lay.rot[ring] + j * lay.dphi[ring])
        return thesis_random(slot_deg, ring, channel)
    return fiber_random(lay.seed, guide, ring, j, channel)


def fiber_center(lay: RingLayout, guide, ring, j):
    """Unit-space centre (x, y) and end parameter v_end of fiber j on ring ``ring`` of guide ``guide``."""
    ring = np.asarray(ring)
    j = np.asarray(j)
    ur = fiber_randoms(lay, guide, ring, j, CH_RADIAL)
    ua = fiber_randoms(lay, guide, ring, j, CH_ANGULAR)
    ul = fiber_randoms(lay, guide, ring, j, CH_LENGTH)
    radius = lay.rho[ring] + (2.0 * ur - 1.0) * lay.max_dr[ring]
    angle = lay.rot[ring] + j * lay.dphi[ring] + (2.0 * ua - 1.0) * lay.max_dphi[ring]
    v_end = 1.0 - lay.length_jitter * ul
    return radius * np.cos(angle), radius * np.sin(angle), v_end


def all_fibers(lay: RingLayout, guide: int):
    """(ring, j, cx, cy, v_end) of every fiber of a container, in its flat fiber numbering."""
    ring = np.repeat(np.arange(lay.rings), lay.n)
    j = np.arange(lay.fibers_per_container) - np.repeat(lay.first, lay.n)
    cx, cy, v_end = fiber_center(lay, guide, ring, j)
    return ring, j, cx, cy, v_end
