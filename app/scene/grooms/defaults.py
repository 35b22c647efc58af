"""Per-groom defaults (``fibers.groom_auto``): interpolated children for curls tighter than a container,
then rings, spacing, fiber thickness and a soft clump edge chosen from the groom itself, so that each shared
groom looks right without hand-tuning.

First the children (``scene.groom_children``, :func:`auto_children`): a groom whose containers fold back
at many of their joints (the container wider than the curl: Curly_100) gets thinner containers between its
strands until few fold; every other groom gets none. Then two facts decide the fibers: the container radius
R (0.75 x the median root spacing, times ``scene.groom_radius_scale``: :func:`~.guides.default_radius`,
narrowed by the children: :func:`~.children.radius_scale`) and the size of a pixel at the default
camera, which frames the whole groom: ``PX_PER_HALF_DIAGONAL`` x half the groom's bounding-box diagonal at
640x360 (the command line's default size). From R / pixel:

* fiber width: ``FIBER_WIDTH_PX`` at that size, so a fiber is a pixel or less wide (fibers.fiber_radius is a
  fraction of R), but never more than ``MAX_RING_FILL`` of a ring's width;
* rings: about one per pixel of container radius, 2 .. 10 (a container one pixel across needs no ten rings);
* spacing: equal arc length on every ring (even_spacing 1: the same fibers per area from core to rim) and as
  many fibers as make the core opaque, ``CORE_DEPTH`` fibers deep along a ray through the axis; containers
  under ``SMALL_CONTAINER_PX`` in radius have no opaque core and get deeper, so that their fibers' summed
  width per pixel of container width stays what a container of that size has (:func:`core_depth`);
* the clump profile: the outer ``EDGE_WIDTH`` of the radius thins to ``EDGE_DENSITY``, so no container
  shows a wall and neighbours blend (from ``EDGE_MIN_RINGS`` rings up).

Whatever a person set (a preset's keys, ``--set``) wins: only keys they did not give take these values.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...params import Params
from . import children
from .guides import resample_many

AUTO_KEYS = ("scene.groom_children", "fibers.rings", "fibers.phi_step", "fibers.phi_increment", "fibers.even_spacing",
             "fibers.fiber_radius", "fibers.edge_density", "fibers.edge_width")
PX_PER_HALF_DIAGONAL = 0.0048
"""A pixel at the default camera and 640x360, over half the groom's bounding-box diagonal: measured 0.0044
(Curly_100) .. 0.0051 (Ratboy_mohawk) on the five shared grooms (the camera frames the containers, not the
box, so it varies a little with the shape)."""
FIBER_WIDTH_PX = 0.5
MAX_RING_FILL = 0.8            # a fiber's diameter at most this fraction of its ring's width
CORE_DEPTH = 10.0              # fibers a ray through the axis meets on average (6 left Curly 27 deg off)
SMALL_CONTAINER_PX = 2.0
"""Below this radius in pixels a container has no opaque core to speak of: every pixel it covers is a rim
pixel, hit about as often as its fibers' summed width across the container per pixel of the container's
width. With fibers of a fixed width in pixels that is depth x radius_px / 2, so a smaller container keeps
the value of one this size and its depth grows as 1 / radius (half the fibers at half the radius, not a
quarter). Ratboy_mohawk's 0.99 px containers at depth 10 lost coverage against the strand reference (IoU
0.895, against 0.906 with vfiber's plain defaults); at 20 they keep it (0.903): its spikes are one or two
containers across."""
MIN_RINGS, MAX_RINGS = 2, 10
FOLD_TRIGGER = 0.10
"""``auto_children`` adds children to a groom only when more than this share of its joints fold their
containers back: Curly_100 62%, Bangs_100 3% (a few kinked strands, which children made worse: IoU 0.929
-> 0.903-0.922 with one child each), the other shared grooms under 1%."""
MAX_FOLD = 0.025
"""... and then as many as leave at most this share folding (Curly_100: 15 children, 2.3%; 12 leave 4.3%,
20 leave 1.1%): see docs/grooms.md, "Curly: interpolated children"."""
FOLD_SAMPLE = 2000             # strands the fold is judged on (auto_children)
EDGE_DENSITY, EDGE_WIDTH = 0.3, 0.5
EDGE_MIN_RINGS = 4             # fewer rings are too coarse for a profile: thinning ring 0 of 2 thins 3/4 of the area


@dataclass(frozen=True)
class GroomDefaults:
    values: dict            # the auto values, every key of AUTO_KEYS
    applied: dict           # those that were used (the rest were set by a person)
    radius: float           # R, world units
    pixel: float            # the pixel's size at the default camera and 640x360, world units
    reason: str


def core_depth(ratio: float) -> float:
    """Fibers a ray through the axis meets, for containers ``ratio`` pixels in radius (see
    :data:`SMALL_CONTAINER_PX`)."""
    return CORE_DEPTH * max(1.0, SMALL_CONTAINER_PX / ratio)


def auto_children(strands, radius: float, segments: int = 1, seed: int = 0) -> int:
    """Interpolated children per guide (``scene.groom_children``) for one guide per strand of radius
    ``radius``. None unless more than ``FOLD_TRIGGER`` of the guides' joints fold their containers back
    (:func:`~.segments.fold_fraction`) at the scene's segment count (``segments``; 1: automatic, as the build
    chooses it for the radius); then the fewest that bring that share to ``MAX_FOLD`` or less, up to
    ``children.MAX_CHILDREN``. Judged on a seeded sample of at most ``FOLD_SAMPLE`` strands."""
    from .segments import auto_segments, fold_fraction

    if len(strands) > FOLD_SAMPLE:
        pick = np.sort(np.random.default_rng(seed).choice(len(strands), FOLD_SAMPLE, replace=False))
        strands = [strands[i] for i in pick]

    def folds(n_children: int) -> float:
        r = radius * children.radius_scale(n_children)
        n = segments if segments > 1 else auto_segments(strands, np.full(len(strands), r), seed=seed)[0]
        return fold_fraction(resample_many(strands, n), r)

    if folds(0) <= FOLD_TRIGGER:
        return 0
    return next((n for n in range(1, children.MAX_CHILDREN) if folds(n) <= MAX_FOLD), children.MAX_CHILDREN)


def auto_fibers(radius: float, pixel: float, rings: int | None = None, fiber_radius: float | None = None) -> dict:
    """The fiber parameters for containers of radius ``radius`` seen at ``pixel`` world units a pixel;
    ``rings`` or ``fiber_radius`` given (a person's) are kept, and the rest follow from them."""
    ratio = radius / pixel
    if rings is None:
        rings = int(np.clip(round(ratio), MIN_RINGS, MAX_RINGS))
    if fiber_radius is None:
        fiber_radius = min(0.5 * FIBER_WIDTH_PX / ratio, MAX_RING_FILL * 0.5 / rings)
    if fiber_radius <= 0:
        return {"fibers.rings": rings, "fibers.fiber_radius": fiber_radius}   # no fibers: nothing to space
    # per unit area of the unit disc: a ray along a diameter (length 2) sweeps 2 * (2 r) of area
    per_area = core_depth(ratio) / (4.0 * fiber_radius)
    # with even spacing ring i holds 360 rho_i / (phi_step rho_0) fibers on an annulus of area 2 pi rho_i / K
    rho0 = 1.0 - 0.5 / rings
    phi_step = float(np.clip(360.0 * rings / (2.0 * math.pi * rho0 * per_area), 0.01, 180.0))
    return {"fibers.rings": rings, "fibers.phi_step": round(phi_step, 4), "fibers.phi_increment": 0.0,
            "fibers.even_spacing": 1.0, "fibers.fiber_radius": round(fiber_radius, 6),
            "fibers.edge_density": EDGE_DENSITY if rings >= EDGE_MIN_RINGS else 1.0, "fibers.edge_width": EDGE_WIDTH}


def groom_defaults(p: Params, given: set[str] | frozenset[str] = frozenset()) -> tuple[Params, GroomDefaults]:
    """``p`` with the per-groom fiber defaults in every key of :data:`AUTO_KEYS` not in ``given``."""
    from .build import groom_of
    from .guides import strands_to_guides

    groom = groom_of(p)
    # the root-spacing radius exactly as the scene's build finds it (build.groom_scene)
    base = strands_to_guides(groom, 1, seed=p["scene.seed"])
    radius = float(base.radii[0]) * p["scene.groom_radius_scale"]
    kept = [groom.strands[i] for i in np.flatnonzero(base.labels >= 0)]
    clustered = 0 < p["scene.groom_cluster"] < len(kept)
    if "scene.groom_children" in given:
        per_guide = p["scene.groom_children"]
    elif clustered:
        per_guide = 0               # clusters are thick on purpose: the person asked for few clumps
    else:
        per_guide = auto_children(kept, radius, p["scene.segments"], p["scene.seed"])
    if not clustered:
        radius *= children.radius_scale(per_guide)
    lo, hi = groom.bbox()
    pixel = max(PX_PER_HALF_DIAGONAL * 0.5 * float(np.linalg.norm(hi - lo)), 1e-30)
    values = auto_fibers(radius, pixel, p["fibers.rings"] if "fibers.rings" in given else None,
                         p["fibers.fiber_radius"] if "fibers.fiber_radius" in given else None)
    values["scene.groom_children"] = per_guide
    applied = {k: v for k, v in values.items() if k not in given}
    reason = (f"{per_guide} interpolated children per strand; " if per_guide else "")
    reason += (f"containers {radius / pixel:.2f} px in radius at the default camera (640x360): fibers "
              f"{2 * values['fibers.fiber_radius'] * radius / pixel:.2f} px wide, {values['fibers.rings']} rings, "
              f"{core_depth(radius / pixel):.3g} fibers deep through the core, the outer "
              f"{values['fibers.edge_width']:g} of the radius at {values['fibers.edge_density']:g} of the core's "
              f"density")
    out = p.replace(**applied)
    return out, GroomDefaults(values, applied, radius, pixel, reason)


def auto_report(p: Params) -> str | None:
    """For ``vfiber info``: what ``fibers.groom_auto`` chose for this groom and which of it ``p`` carries
    (a value that differs was set by a person and won). None when it is off or not a groom."""
    if not (p["fibers.groom_auto"] and p["scene.generator"] == "groom"):
        return None
    _, d = groom_defaults(p)
    # children, rings and fiber radius decide the rest: a person's value there is taken as given, then compared
    primary: set[str] = set()
    for key in ("scene.groom_children", "fibers.rings", "fibers.fiber_radius"):   # each follows the one before
        if p[key] != d.values[key]:
            primary.add(key)
            _, d = groom_defaults(p, primary)
    kept = sorted(primary | {k for k, v in d.values.items() if p[k] != v}, key=AUTO_KEYS.index)
    chosen = ", ".join(f"{k.split('.', 1)[1]} {v:g}" for k, v in d.values.items() if k not in kept)
    text = f"{chosen or 'nothing'}: {d.reason}"
    return text + (f"; set by you, kept: {', '.join(f'{k} = {p[k]:g}' for k in kept)}" if kept else "")
