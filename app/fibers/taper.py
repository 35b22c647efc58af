"""Tip taper: each virtual fiber thins toward its own tip (issue 15), so its end is a point, not a cut disc.

Along its own length (guide parameter v from the root, 0, to the fiber's end v_end) a fiber's width, as a
fraction of its root width ``fibers.fiber_radius``, is

    g(v) = 1                                              v <= v_s = taper_start * v_end
    g(v) = 1 - (1 - tip_width) (v - v_s) / (v_end - v_s)  v_s <= v <= v_end

Inside one container segment the traversal works in unit space, where the fiber is a vertical line and a
ray is a straight line; there the width is kept *linear in the unit-space height Z*, so that the fiber's
tapering part is a cone and a ray meets it in one quadratic. The line L(Z) = l0 + l1 Z of a segment passes
through g's values at the two ends of the part of the segment where the fiber thins (the later of the
segment's root and v_s; the earlier of its tip and v_end): exact there, and so continuous from segment to
segment, reaching tip_width exactly at the fiber's tip. In between it is the chord of g, because the
unit-space height is not linear in v on a tapered container (Z = z / (r0 + kappa z)); linear in Z is the
same as linear in the local height z, so the cone is a straight cone in the world too. With kappa = 0 the
chord is g itself.

The fiber in the segment is then {|p - c| <= fiber_radius * min(1, L(Z)), L(Z) >= 0}: the root-width
cylinder cut by the cone (L extrapolated past the thinning part only widens toward the root, where the
cylinder caps it, and ends at the apex, L = 0). Both are convex, so a ray's interval in the fiber is the
intersection of its intervals in each, as the length cut already was: never wider than today's cylinder,
so every traversal bound (slots, reach, candidate windows) holds unchanged.

GLSL twin: glsl/fibers/taper.glsl; OSL: osl/fibers/taper.osl; the judge: app/reference.py (brute_nearest,
piece_entry); the explicit baseline: glsl/explicit/ribbon.vert.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

TAPER_KEYS = ("strand.tip_width", "strand.taper_start")


@dataclass(frozen=True)
class Taper:
    tip_width: float = 1.0     # width at the fiber's own tip / root width
    start: float = 0.5         # fraction of the fiber's length where thinning begins

    @staticmethod
    def from_params(p) -> Taper:
        return Taper(float(p["strand.tip_width"]), float(p["strand.taper_start"]))

    @property
    def on(self) -> bool:
        """Whether any fiber thins: at tip_width 1 the fibers are today's cylinders and the shaders are
        built without the cone (TAPER 0), so nothing else moves."""
        return self.tip_width < 1.0


def tapered(p) -> bool:
    return Taper.from_params(p).on


def taper_line(taper: Taper, v0, v1, z_scale, r0, kappa, v_end):
    """(l0, l1): the width fraction L(Z) = l0 + l1 Z over one segment's unit-space height Z for fibers
    ending at ``v_end`` (arrays broadcast). The segment runs from guide parameter v0 to v1, z_scale =
    h / (v1 - v0) turns guide parameter into local height, r0 is its root radius and kappa its slope
    (glsl/fibers/taper.glsl: taper_line)."""
    v_end = np.asarray(v_end, np.float64)
    v_s = taper.start * v_end
    # the fall of g per unit v; a fiber of no length has none (and no fiber: v_end <= v0)
    span = (1.0 - taper.start) * v_end
    dgdv = -(1.0 - taper.tip_width) / np.maximum(span, 1e-30)
    v_a = np.clip(v_s, v0, v1)
    v_b = np.minimum(v_end, v1)
    g_a = 1.0 + dgdv * np.maximum(0.0, v_a - v_s)
    zeta_a = (v_a - v0) * z_scale
    w_a = r0 + kappa * zeta_a
    w_b = r0 + kappa * (v_b - v0) * z_scale
    # the chord's slope in Z: (v_b - v_a) / (Z_b - Z_a) = w_a w_b / (r0 z_scale), without the difference
    l1 = np.where(v_a < v_b, dgdv * w_a * w_b / (r0 * z_scale), 0.0)
    l0 = g_a - l1 * (zeta_a / w_a)
    return l0, l1


def taper_apex(l0, l1):
    """Unit-space height where the width reaches 0 (inf where it does not thin): the fiber ends there at
    the latest."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(l1 < 0, -l0 / np.where(l1 < 0, l1, -1.0), np.inf)
