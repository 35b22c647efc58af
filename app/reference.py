"""The float64 reference: container geometry and a brute-force nearest hit, in numpy.

It is the judge of the shader and stands beside the renderer, never under it: both import the fiber
model (where fibers sit, the hash, the shape) from ``app.fibers``; the renderer never imports this module.
Every function here has a GLSL twin of the same name (in ``glsl/``; docs/architecture.md, "Twins"), and
the tests hold one against the other. The reference tests *every* fiber of every ring for every ray, so it
is slow and simple on purpose.

Geometry, in words (the GLSL files say the same thing in code):

* A container segment has a local frame (ex, ey, ez), ez along its axis, and radius w(z) = r0 + kappa*z.
* The projective map P' = P / w(z) turns the (possibly tapered) container into a unit cylinder and every
  fiber into a straight vertical cylinder of radius ``fiber_radius``: lines stay lines and the order of
  points along a ray is kept where w > 0, so the nearest hit in that "unit space" is the nearest hit.
* Ring i (0 = outermost) is the annulus [1 - (i+1)/K, 1 - i/K] of unit space; its fibers sit at
  angles rot_i + j * dphi_i, with radial and angular jitter bounded so that a fiber never leaves its
  slot (thesis 3.5).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import fibers
# The model itself (placement, hash, shape) is app.fibers'; it is named here too so that a test holds a
# GLSL function against ``reference.NAME`` whichever side of the line between model and judge it sits on.
from .fibers import (CH_ANGULAR, CH_CURL, CH_LENGTH, CH_RADIAL, CH_RING, CH_ROUGH, CH_TINT,  # noqa: F401
                     CURL_PATTERNS, LAYOUT_KEYS, THESIS_LCG, TWIST_PATTERNS, RingLayout, Shape, Taper, all_fibers,
                     fiber_center, fiber_center_at, fiber_count, fiber_hash, fiber_key, fiber_random,
                     fiber_randoms, key_random, lowbias32, ring_key, ring_layout, shape_scale, shape_twist,
                     taper_apex, taper_line, thesis_random)
from .params import Params
from .scene.containers import Scene


# --------------------------------------------------------------------------------------------------
# Container segment geometry (glsl/geometry/container.glsl)
# --------------------------------------------------------------------------------------------------
@dataclass
class Segment:
    p0: np.ndarray
    ex: np.ndarray
    ey: np.ndarray
    ez: np.ndarray
    h: float
    r0: float
    kappa: float           # dr/dz
    n0: np.ndarray         # joint planes, local frame
    n1: np.ndarray
    v0: float
    v1: float
    guide: int
    z_lo: float            # bounding slab (joint planes reach past the end points)
    z_hi: float
    r_bound: float


def segment(row: np.ndarray) -> Segment:
    row = row.astype(np.float64)
    p0, r0, p1, r1 = row[0:3], row[3], row[4:7], row[7]
    axis = p1 - p0
    h = float(np.linalg.norm(axis))
    ez = axis / h
    ex = row[16:19] - ez * np.dot(row[16:19], ez)
    ex /= np.linalg.norm(ex)
    ey = np.cross(ez, ex)
    frame = np.stack([ex, ey, ez])
    n0, n1 = frame @ row[8:11], frame @ row[12:15]
    r_bound = max(r0, r1)
    z_lo = -r_bound * _slope(n0)
    z_hi = h + r_bound * _slope(n1)
    return Segment(p0, ex, ey, ez, h, r0, (r1 - r0) / h, n0, n1, row[11], row[15], int(row[19]),
                   z_lo, z_hi, r_bound)


def _slope(n: np.ndarray) -> float:
    """How far a joint plane leans past the end point per unit of radius: tan of its tilt."""
    c = abs(n[2])
    return math.sqrt(max(0.0, 1.0 - c * c)) / max(c, 1e-6)


def _slab(o, d, lo, hi):
    """Ray interval inside lo <= o + t d <= hi (per ray; d may be 0)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        ta, tb = (lo - o) / d, (hi - o) / d
    t0 = np.where(d != 0, np.minimum(ta, tb), np.where((o >= lo) & (o <= hi), -np.inf, np.inf))
    t1 = np.where(d != 0, np.maximum(ta, tb), np.where((o >= lo) & (o <= hi), np.inf, -np.inf))
    return t0, t1


def circle_interval(ox, oy, dx, dy, cx, cy, r):
    """Ray interval inside the infinite vertical cylinder of radius r about (cx, cy).

    Stable roots (pbrt's q = -(b + sign(b) sqrt(disc)), t0 = q/a, t1 = c/q) with a cancellation-free
    discriminant a r^2 - cross^2 = (sqrt(a) r - |cross|)(sqrt(a) r + |cross|): a ray tilted 1e-7 from the
    axis keeps its near root. A ray parallel to the axis (a = 0) is inside for all t or never.
    """
    ocx, ocy = ox - cx, oy - cy
    a = dx * dx + dy * dy
    b = ocx * dx + ocy * dy
    c = (np.hypot(ocx, ocy) - r) * (np.hypot(ocx, ocy) + r)
    cross = np.abs(ocx * dy - ocy * dx)
    ra = np.sqrt(a) * r
    disc = (ra - cross) * (ra + cross)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        q = -(b + np.where(b >= 0, 1.0, -1.0) * np.sqrt(np.maximum(disc, 0.0)))
        t_a = q / a
        t_b = np.where(q != 0, c / q, t_a)
    par = a == 0
    hit = np.where(par, c <= 0, disc >= 0)
    t0 = np.where(par, -np.inf, np.minimum(t_a, t_b))
    t1 = np.where(par, np.inf, np.maximum(t_a, t_b))
    return np.where(hit, t0, np.inf), np.where(hit, t1, -np.inf)


def cone_interval(ox, oy, dx, dy, cx, cy, rho0, rho1):
    """Ray interval inside the cone |p(t) - c| <= rho0 + rho1 t about the vertical axis through (cx, cy)
    (p the ray's xy; the radius is linear in t because it is linear in the unit-space height), on the
    side of the apex where the radius is positive; the caller cuts at the apex (glsl/fibers/taper.glsl:
    cone_interval). f(t) = |p - c|^2 - rho^2 = a t^2 + 2 b t + c with a = |d|^2 - rho1^2: a > 0 (the ray
    shallower than the cone's side) meets it between the roots; a < 0 (steeper) outside them, and only
    the half toward the widening side is this nappe. Roots and discriminant as circle_interval's: disc =
    |rho0 d - rho1 (o - c)|^2 - cross^2, factored, which for rho1 = 0 is the cylinder's."""
    ocx, ocy = ox - cx, oy - cy
    dlen = np.hypot(dx, dy)
    a = (dlen - np.abs(rho1)) * (dlen + np.abs(rho1))
    b = ocx * dx + ocy * dy - rho0 * rho1
    oc = np.hypot(ocx, ocy)
    c = (oc - rho0) * (oc + rho0)
    cross = np.abs(ocx * dy - ocy * dx)
    m = np.hypot(rho0 * dx - rho1 * ocx, rho0 * dy - rho1 * ocy)
    disc = (m - cross) * (m + cross)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        q = -(b + np.where(b >= 0, 1.0, -1.0) * np.sqrt(np.maximum(disc, 0.0)))
        t_a = q / np.where(a != 0, a, 1.0)
        t_b = np.where(q != 0, c / q, t_a)
    lo, hi = np.minimum(t_a, t_b), np.maximum(t_a, t_b)
    inside = disc >= 0
    t0 = np.where(a > 0, np.where(inside, lo, np.inf), np.where(rho1 > 0, hi, -np.inf))
    t1 = np.where(a > 0, np.where(inside, hi, -np.inf), np.where(rho1 > 0, np.inf, lo))
    # a = 0: the ray parallel to a side line; f is linear, 2 b t + c, and t_b its root
    t0 = np.where(a == 0, np.where(b < 0, t_b, np.where(b > 0, -np.inf, np.where(c <= 0, -np.inf, np.inf))), t0)
    t1 = np.where(a == 0, np.where(b > 0, t_b, np.where(b < 0, np.inf, np.where(c <= 0, np.inf, -np.inf))), t1)
    return t0, t1


@dataclass
class UnitRays:
    """Rays of one segment in unit space: O + s D (D unit), valid over [s0, s1] (inside the container)."""
    idx: np.ndarray        # which input rays
    tb: np.ndarray         # world t of the unit-space origin
    o: np.ndarray          # local-space origin (N,3) at tb
    d: np.ndarray          # local-space unit direction
    w_o: np.ndarray
    O: np.ndarray
    D: np.ndarray
    D_len: np.ndarray
    s0: np.ndarray
    s1: np.ndarray


def to_unit_space(seg: Segment, ro: np.ndarray, rd: np.ndarray, t_near: float = 0.0) -> UnitRays:
    """Rays (world, relative to the same origin as the segment) that enter the segment's container."""
    frame = np.stack([seg.ex, seg.ey, seg.ez])
    o = (ro - seg.p0) @ frame.T
    d = rd @ frame.T
    # bounding cylinder and slab: cheap, conservative, and where w(z) > 0
    c0, c1 = circle_interval(o[:, 0], o[:, 1], d[:, 0], d[:, 1], 0.0, 0.0, seg.r_bound * (1 + 1e-4))
    z0, z1 = _slab(o[:, 2], d[:, 2], seg.z_lo, seg.z_hi)
    tb0 = np.maximum(np.maximum(c0, z0), t_near)
    tb1 = np.minimum(c1, z1)
    keep = np.nonzero(tb0 <= tb1)[0]
    o, d, tb0 = o[keep], d[keep], tb0[keep]
    o = o + tb0[:, None] * d
    w_o = seg.r0 + seg.kappa * o[:, 2]
    O = o / w_o[:, None]
    D = d * w_o[:, None] - o * (seg.kappa * d[:, 2])[:, None]
    D_len = np.linalg.norm(D, axis=1)
    D = D / D_len[:, None]
    # the container in unit space: unit cylinder, root-side joint plane, tip-side joint plane
    s0, s1 = circle_interval(O[:, 0], O[:, 1], D[:, 0], D[:, 1], 0.0, 0.0, 1.0)
    s0 = np.maximum(s0, 0.0)
    for m, c in ((-seg.r0 * seg.n0, 0.0),
                 (seg.r0 * seg.n1 + seg.n1[2] * seg.h * seg.kappa * np.array([0, 0, 1.0]), seg.n1[2] * seg.h)):
        # half-space m . P' <= c
        mo, md = O @ m - c, D @ m
        with np.errstate(divide="ignore", invalid="ignore"):
            tp = -mo / md
        s0 = np.where(md < 0, np.maximum(s0, tp), s0)
        s1 = np.where(md > 0, np.minimum(s1, tp), s1)
        outside = (md == 0) & (mo > 0)
        s1 = np.where(outside, -np.inf, s1)
    return UnitRays(keep, tb0, o, d, w_o, O, D, D_len, s0, s1)


def unit_to_world_t(seg: Segment, ur: UnitRays, s: np.ndarray, sel=slice(None)) -> np.ndarray:
    """World ray parameter of the unit-space point O + s D (the projective map inverted)."""
    sigma = s / ur.D_len[sel]            # parameter along the unnormalised direction
    w_o = ur.w_o[sel]
    dz = ur.d[sel, 2]
    return ur.tb[sel] + sigma * w_o * w_o / (1.0 - sigma * w_o * seg.kappa * dz)


def z_cut_unit(seg: Segment, v_end):
    """Unit-space height where a fiber that ends at guide parameter v_end stops (inf: past this segment)."""
    z = (v_end - seg.v0) / (seg.v1 - seg.v0) * seg.h
    zc = z / (seg.r0 + seg.kappa * z)
    return np.where(v_end >= seg.v1, np.inf, np.where(v_end <= seg.v0, -np.inf, zc))


# --------------------------------------------------------------------------------------------------
# Brute-force nearest hit
# --------------------------------------------------------------------------------------------------
@dataclass
class Hits:
    t: np.ndarray          # world distance along the ray, inf on a miss
    guide: np.ndarray      # -1 on a miss
    segment: np.ndarray
    ring: np.ndarray
    fiber: np.ndarray

    @property
    def hit(self) -> np.ndarray:
        return self.guide >= 0


def brute_nearest(scene: Scene, p: Params, ro: np.ndarray, rd: np.ndarray, t_near: float = 0.0,
                  chunk: int = 4_000_000) -> Hits:
    """Nearest fiber hit for each ray (ro, rd world float64; rd unit). Tests every fiber of every ring."""
    ro = np.asarray(ro, np.float64).reshape(-1, 3) - scene.origin
    rd = np.asarray(rd, np.float64).reshape(-1, 3)
    n = len(ro)
    out = Hits(np.full(n, np.inf), np.full(n, -1), np.full(n, -1), np.full(n, -1), np.full(n, -1))
    lay = ring_layout(p)
    rf = lay.fiber_radius
    sh = Shape.from_params(p)
    taper = Taper.from_params(p)
    fibers_cache: dict[int, tuple] = {}
    for si, row in enumerate(scene.segments):
        seg = segment(row)
        ur = to_unit_space(seg, ro, rd, t_near)
        live = np.nonzero(ur.s0 <= ur.s1)[0]
        if not len(live) or rf <= 0:
            continue
        if sh.curved:
            s_best, ring_b, j_b = shaped_nearest_segment(sh, lay, seg, ur, live, taper=taper)
            ok = np.isfinite(s_best)
            rows = live[ok]
            t = unit_to_world_t(seg, ur, s_best[ok], rows)
            ray = ur.idx[rows]
            closer = t < out.t[ray]
            ray, t = ray[closer], t[closer]
            out.t[ray] = t
            out.guide[ray] = seg.guide
            out.segment[ray] = si
            out.ring[ray] = ring_b[ok][closer]
            out.fiber[ray] = j_b[ok][closer]
            continue
        if seg.guide not in fibers_cache:
            fibers_cache[seg.guide] = all_fibers(lay, seg.guide)
        ring, j, cx, cy, v_end = fibers_cache[seg.guide]
        zc = z_cut_unit(seg, v_end)
        if taper.on:
            # app/fibers/taper.py: the root-width cylinder cut by the cone, which ends at its apex
            l0, l1 = taper_line(taper, seg.v0, seg.v1, seg.h / (seg.v1 - seg.v0), seg.r0, seg.kappa, v_end)
            zc = np.minimum(zc, taper_apex(l0, l1))
        step = max(1, chunk // max(1, len(cx)))
        for a in range(0, len(live), step):
            sel = live[a:a + step]
            O, D = ur.O[sel], ur.D[sel]
            # each fiber at its ring's radius (the clump profile thins the outer rings': ring_radius)
            c0, c1 = circle_interval(O[:, :1], O[:, 1:2], D[:, :1], D[:, 1:2], cx[None], cy[None],
                                     lay.ring_radius[ring][None])
            z0, z1 = _slab(O[:, 2:3], D[:, 2:3], -np.inf, zc[None])
            s_in = np.maximum(np.maximum(c0, z0), ur.s0[sel, None])
            s_out = np.minimum(np.minimum(c1, z1), ur.s1[sel, None])
            if taper.on:
                rr = lay.ring_radius[ring][None]             # each fiber's ring's radius
                k0, k1 = cone_interval(O[:, :1], O[:, 1:2], D[:, :1], D[:, 1:2], cx[None], cy[None],
                                       rr * (l0[None] + l1[None] * O[:, 2:3]), rr * l1[None] * D[:, 2:3])
                s_in, s_out = np.maximum(s_in, k0), np.minimum(s_out, k1)
            s_in = np.where(s_in <= s_out, s_in, np.inf)
            best = np.argmin(s_in, axis=1)
            s_best = s_in[np.arange(len(sel)), best]
            ok = np.isfinite(s_best)
            if not ok.any():
                continue
            rows = sel[ok]
            t = unit_to_world_t(seg, ur, s_best[ok], rows)
            ray = ur.idx[rows]
            closer = t < out.t[ray]
            ray, t, b = ray[closer], t[closer], best[ok][closer]
            out.t[ray] = t
            out.guide[ray] = seg.guide
            out.segment[ray] = si
            out.ring[ray] = ring[b]
            out.fiber[ray] = j[b]
    return out


def rings_crossed(scene: Scene, p: Params, ro, rd, t_near: float = 0.0) -> np.ndarray:
    """Per ray, the number of ring annuli its path through the containers touches, summed over containers:
    the floor of fiber tests that a traversal visiting one fiber per ring piece could reach."""
    ro = np.asarray(ro, np.float64).reshape(-1, 3) - scene.origin
    rd = np.asarray(rd, np.float64).reshape(-1, 3)
    K = p["fibers.rings"]
    count = np.zeros(len(ro), np.int64)
    for row in scene.segments:
        seg = segment(row)
        ur = to_unit_space(seg, ro, rd, t_near)
        live = ur.s0 <= ur.s1
        # closest approach of the track to the axis inside [s0, s1]
        Dxy = ur.D[:, :2]
        a = (Dxy ** 2).sum(1)
        with np.errstate(divide="ignore", invalid="ignore"):
            s_star = np.where(a > 0, -(ur.O[:, :2] * Dxy).sum(1) / a, ur.s0)
        s_star = np.clip(s_star, ur.s0, np.maximum(ur.s0, ur.s1))
        pts = ur.O[:, :2] + s_star[:, None] * Dxy
        r_min = np.sqrt((pts ** 2).sum(1))
        deepest = np.minimum(K - 1, np.floor((1.0 - r_min) * K)).astype(np.int64)
        np.add.at(count, ur.idx[live], deepest[live] + 1)
    return count


# --------------------------------------------------------------------------------------------------
# Curved fibers (glsl/fibers/curved.glsl, shaped.glsl: traverse_shaped; the shape is app/fibers/shape.py)
# --------------------------------------------------------------------------------------------------
MAX_SUB = fibers.MAX_SUB


def unit_to_v(seg: Segment, z_unit):
    z = seg.r0 * z_unit / (1.0 - seg.kappa * z_unit)
    return seg.v0 + (seg.v1 - seg.v0) * z / seg.h


def ring_point(seg: Segment, O, D, s):
    """The ray at s: (v, x, y), (x, y) = O.xy + s D.xy in the container's frame. (The GLSL's also carries
    the ring's scale and twist there, which it turns the fibers by; piece_entry here takes them from
    fiber_center_at.)"""
    v = unit_to_v(seg, O[..., 2] + s * D[..., 2])
    return v, O[..., 0] + s * D[..., 0], O[..., 1] + s * D[..., 1]


def chord_pieces(sh: Shape, lay: RingLayout, dv, ring, e_lo: float):
    """Chord pieces for an arc that climbs ``dv`` (curved.glsl: chord_pieces): the fibers' centre lines
    bend at most ``bend_v`` per unit v squared."""
    rho = lay.rho[ring] + lay.max_dr[ring]
    rate = 2 * math.pi * abs(sh.twist) * (2.0 if sh.twist_pattern == fibers.TWIST_RAMPED else 1.0)
    rate2 = 2.0 * 2 * math.pi * abs(sh.twist) if sh.twist_pattern == fibers.TWIST_RAMPED else 0.0
    f = 2 * math.pi * sh.curl_frequency
    helix = sh.curl_pattern == fibers.CURL_HELIX
    curl = sh.curl_amplitude * (f * f if helix else (f + rate) ** 2 + rate2)   # the wave turns with the twist
    fz, fn = 2 * math.pi * sh.frizz_frequency_max + rate, 2 * math.pi * sh.noise_frequency + rate
    curl = curl + sh.frizz_amplitude * (fz * fz + rate2) + sh.noise_amplitude * (fn * fn + rate2)
    e = np.maximum(e_lo, 0.25)
    e2 = 4.0 * sh.ellipsoid ** 2
    bend_v = rho * (rate * rate + rate2 + e2 / e ** 3 + e2 * rate / e) + curl
    n = np.ceil(np.sqrt(dv * dv * bend_v / (0.8 * max(lay.fiber_radius, 1e-30))))
    return np.clip(n, 1, MAX_SUB).astype(np.int64)


def segment_bands(sh: Shape, seg: Segment) -> tuple[float, float]:
    v_lo = unit_to_v(seg, seg.z_lo / (seg.r0 + seg.kappa * seg.z_lo))
    v_hi = unit_to_v(seg, seg.z_hi / (seg.r0 + seg.kappa * seg.z_hi))
    ea, eb = float(shape_scale(sh, v_lo)), float(shape_scale(sh, v_hi))
    e_hi = 1.0 if min(v_lo, v_hi) <= 0.5 <= max(v_lo, v_hi) else max(ea, eb)
    return min(ea, eb), e_hi


def piece_entry(sh, lay, seg, O, D, P0, P1, s_a, s_b, rest_x, rest_y, phase, v_end, taper: Taper | None = None,
                ring: int = 0):
    """Entry parameter of each (ray, fiber) pair over the chord piece [s_a, s_b] (curved.glsl: piece_entry):
    the fiber stands for the chord between its centres at the piece's ends (fiber_center_at), so the ray
    seen from it runs from P0.xy - c(P0) to P1.xy - c(P1) on a line. inf on a miss.
    A tapered fiber's width is linear in the ray's unit-space height, so along the piece it is linear in s
    too: the cone of ``cone_interval`` about the moving centre. The fibers are ring ``ring``'s, at its
    radius (``lay.ring_radius``)."""
    zc = z_cut_unit(seg, v_end)
    tapering = taper is not None and taper.on
    if tapering:
        l0, l1 = taper_line(taper, seg.v0, seg.v1, seg.h / (seg.v1 - seg.v0), seg.r0, seg.kappa, v_end)
        zc = np.minimum(zc, taper_apex(l0, l1))
    z0, z1 = _slab(O[..., 2], D[..., 2], -np.inf, zc)
    lo, hi = np.maximum(s_a, z0), np.minimum(s_b, z1)
    c0x, c0y = fibers.fiber_center_at(sh, rest_x, rest_y, P0[0], ring, phase)
    c1x, c1y = fibers.fiber_center_at(sh, rest_x, rest_y, P1[0], ring, phase)
    q0x, q0y = P0[1] - c0x, P0[2] - c0y
    q1x, q1y = P1[1] - c1x, P1[2] - c1y
    length = s_b - s_a
    safe = np.where(length > 0, length, 1.0)
    dqx = np.where(length > 0, (q1x - q0x) / safe, 0.0)
    dqy = np.where(length > 0, (q1y - q0y) / safe, 0.0)
    rf = lay.ring_radius[ring]
    e0, e1 = circle_interval(q0x, q0y, dqx, dqy, 0.0, 0.0, rf)
    if tapering:
        k0, k1 = cone_interval(q0x, q0y, dqx, dqy, 0.0, 0.0, rf * (l0 + l1 * (O[..., 2] + s_a * D[..., 2])),
                               rf * l1 * D[..., 2])
        e0, e1 = np.maximum(e0, k0), np.minimum(e1, k1)
    s_in = np.maximum(s_a + e0, lo)
    s_out = np.minimum(s_a + e1, hi)
    return np.where((zc != -np.inf) & (s_in <= s_out), s_in, np.inf)


def shaped_nearest_segment(sh: Shape, lay: RingLayout, seg: Segment, ur: UnitRays, live: np.ndarray,
                           chunk: int = 2_000_000, taper: Taper | None = None):
    """Nearest curved-fiber hit of the rays ``live`` in one segment: (s, ring, fiber) arrays, brute force
    over the same arcs and chord pieces the shader walks (glsl/fibers/shaped.glsl): every fiber of a ring
    on each piece of each arc of that ring."""
    O, D, s0, s1 = ur.O[live], ur.D[live], ur.s0[live], ur.s1[live]
    n_rays = len(live)
    best_s = np.full(n_rays, np.inf)
    best_ring = np.full(n_rays, -1)
    best_j = np.full(n_rays, -1)
    e_lo, e_hi = segment_bands(sh, seg)
    o2, d2 = O[:, :2], D[:, :2]
    a2 = (d2 ** 2).sum(1)
    with np.errstate(divide="ignore", invalid="ignore"):
        s_mid = np.where(a2 > 0, -(o2 * d2).sum(1) / a2, s0)
    once_seen = np.zeros(n_rays, bool)
    stopped = np.zeros(n_rays, bool)
    grow = lay.fiber_radius + sh.displacement + 1e-6
    for i in range(lay.rings):
        inner_r = max(0.0, e_lo * (lay.rho[i] - lay.max_dr[i]) - grow)
        outer_r = e_hi * (lay.rho[i] + lay.max_dr[i]) + grow
        ox0, ox1 = circle_interval(o2[:, 0], o2[:, 1], d2[:, 0], d2[:, 1], 0.0, 0.0, outer_r)
        ix0, ix1 = circle_interval(o2[:, 0], o2[:, 1], d2[:, 0], d2[:, 1], 0.0, 0.0, inner_r)
        stopped |= ox0 > ox1
        twice = ~stopped & (ix0 <= ix1) & ~once_seen
        once = ~stopped & ~twice
        once_seen |= once
        arcs = [(ox0, np.where(twice, ix0, s_mid)), (np.where(twice, ix1, s_mid), ox1)]
        j = np.arange(lay.n[i])
        rest_x, rest_y, v_end = fiber_center(lay, seg.guide, np.full_like(j, i), j)
        phase = fiber_randoms(lay, seg.guide, np.full_like(j, i), j, CH_CURL)
        for side, (sA, sB) in enumerate(arcs):
            sA = np.maximum(sA, s0)
            sB = np.minimum(sB, s1)
            rows = np.nonzero(~stopped & (sA <= sB))[0]
            step_rows = max(1, chunk // max(1, len(j)))
            for c in range(0, len(rows), step_rows):
                r = rows[c:c + step_rows]
                a, b = sA[r], sB[r]
                Or, Dr = O[r], D[r]
                e_lo_arc = e_lo
                if sh.ellipsoid > 0:
                    # shaped.glsl: the arc's heights bound the scale tighter; the band shrinks to match
                    va, vb = unit_to_v(seg, Or[:, 2] + a * Dr[:, 2]), unit_to_v(seg, Or[:, 2] + b * Dr[:, 2])
                    ea, eb = shape_scale(sh, va), shape_scale(sh, vb)
                    e_lo_arc = np.minimum(ea, eb)
                    e_hi_arc = np.where((np.minimum(va, vb) <= 0.5) & (np.maximum(va, vb) >= 0.5), 1.0,
                                        np.maximum(ea, eb))
                    t_in = np.maximum(0.0, e_lo_arc * (lay.rho[i] - lay.max_dr[i]) - grow)
                    t_out = e_hi_arc * (lay.rho[i] + lay.max_dr[i]) + grow
                    to0, to1 = circle_interval(o2[r, 0], o2[r, 1], d2[r, 0], d2[r, 1], 0.0, 0.0, t_out)
                    ti0, ti1 = circle_interval(o2[r, 0], o2[r, 1], d2[r, 0], d2[r, 1], 0.0, 0.0, t_in)
                    before = side == 0
                    a = np.maximum(a, to0 if before else ti1)
                    b = np.minimum(b, ti0 if before else to1)
                    keep = a <= b
                    r, a, b, Or, Dr, e_lo_arc = r[keep], a[keep], b[keep], Or[keep], Dr[keep], e_lo_arc[keep]
                    if not len(r):
                        continue
                Pa = ring_point(seg, Or, Dr, a)
                Pb = ring_point(seg, Or, Dr, b)
                n = chord_pieces(sh, lay, np.abs(Pb[0] - Pa[0]), i, e_lo_arc)
                step = (b - a) / n
                s = np.full((len(r), len(j)), np.inf)
                P0, s_k = Pa, a
                for k in range(int(n.max())):
                    last = k == n - 1
                    s_k1 = np.where(last, b, a + (k + 1) * step)
                    P1 = tuple(np.where(last, x, y) for x, y in zip(Pb, ring_point(seg, Or, Dr, s_k1)))
                    col = lambda x: x[:, None]  # noqa: E731
                    hit = piece_entry(sh, lay, seg, Or[:, None, :], Dr[:, None, :], tuple(map(col, P0)),
                                      tuple(map(col, P1)), col(s_k), col(s_k1), rest_x[None], rest_y[None],
                                      phase[None], v_end[None], taper, i)
                    s = np.where(col(k < n), np.minimum(s, hit), s)
                    P0, s_k = P1, s_k1
                k = np.argmin(s, axis=1)
                sk = s[np.arange(len(r)), k]
                better = sk < best_s[r]   # rings come in order; within a ring argmin takes the lower j
                tie = (sk == best_s[r]) & np.isfinite(sk) & ((i < best_ring[r]) |
                                                             ((i == best_ring[r]) & (k < best_j[r])))
                upd = better | tie
                best_s[r[upd]] = sk[upd]
                best_ring[r[upd]] = i
                best_j[r[upd]] = k[upd]
    return best_s, best_ring, best_j


# --- the filtered mode's coverage (glsl/fibers/coverage.glsl) ----------------------------------------------
def tent_cdf(v):
    """The share of a unit tent (half-width 1, area 1) below ``v``: 0 at -1, 1/2 at 0, 1 at 1."""
    v = np.clip(np.asarray(v, np.float64), -1.0, 1.0)
    return np.where(v <= 0.0, 0.5 * (1.0 + v) ** 2, 1.0 - 0.5 * (1.0 - v) ** 2)


def footprint_coverage(x, r, w):
    """The share of a tent footprint of half-width ``w``, centred ``x`` from a fiber's axis, that the fiber
    (a band of half-width ``r`` across the footprint) covers: the integral of the tent over [-r, r]."""
    x, r, w = (np.asarray(a, np.float64) for a in (x, r, w))
    with np.errstate(over="ignore", invalid="ignore"):
        inv = 1.0 / np.maximum(w, 1e-30)
        return np.clip(tent_cdf((r - x) * inv) - tent_cdf((-r - x) * inv), 0.0, 1.0)


# --- the filtered mode's medium (glsl/fibers/coverage.glsl: ring_fence .. cover_medium) --------------------
# The shader's constants (#define there; tests/render/test_filter.py holds them equal).
COVER_OPAQUE = 0.06
COVER_MEDIUM_FROM = 12.0
COVER_MEDIUM_FULL = 20.0
COVER_TENT_MIN = 0.01
COVER_LIGHT_NODES = 5


@dataclass(frozen=True)
class Fence:
    """A ring seen across as a fence (coverage.glsl: ring_fence): at offset u from the axis its fibers cover
    g(u) = min(1, kappa / sqrt(rho^2 - u^2)) of the cross axis, kappa = n rf / pi, 0 past the ring; closed
    (g = 1) from ys = sqrt(rho^2 - kappa^2) out; g1s, g2s: g's first and second antiderivatives at ys."""
    rho: float
    kappa: float
    ys: float
    g1s: float
    g2s: float


def ring_fence(rho: float, n: float, rf: float) -> Fence:
    kappa = n * rf / math.pi
    ys = math.sqrt(max(rho * rho - kappa * kappa, 0.0))
    a_s = math.asin(min(ys / max(rho, 1e-30), 1.0))
    return Fence(rho, kappa, ys, kappa * a_s,
                 kappa * (ys * a_s - ys * ys / (math.sqrt(max(rho * rho - ys * ys, 0.0)) + rho)))


def ring_fence_f2(f: Fence, u):
    """The second antiderivative of the fence's g, even in u, 0 at 0."""
    a = np.abs(np.asarray(u, np.float64))
    rho = max(f.rho, 1e-30)
    opened = f.kappa * (a * np.arcsin(np.minimum(a / rho, 1.0))
                        - a * a / (np.sqrt(np.maximum(f.rho ** 2 - a * a, 0.0)) + f.rho))
    inner = np.minimum(a, f.rho) - f.ys
    closed = f.g2s + (f.g1s + 0.5 * inner) * inner + (f.g1s + f.rho - f.ys) * np.maximum(a - f.rho, 0.0)
    return np.where(a <= f.ys, opened, closed)


def ring_fence_g(f: Fence, u):
    """g itself: the share of the cross axis one arc's fibers cover at offset u."""
    u = np.abs(np.asarray(u, np.float64))
    with np.errstate(divide="ignore"):
        g = np.minimum(1.0, f.kappa / np.sqrt(np.maximum(f.rho ** 2 - u * u, 1e-30)))
    return np.where(u < f.rho, g, 0.0)


def ring_fence_cover(f: Fence, d, w):
    """The share of a tent footprint (half-width w, centre line d from the axis) one arc of the ring covers:
    the tent's second difference of ring_fence_f2 (g where w is below COVER_TENT_MIN of the radius)."""
    d, w = np.asarray(d, np.float64), np.asarray(w, np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        tent = (ring_fence_f2(f, d + w) - 2.0 * ring_fence_f2(f, d) + ring_fence_f2(f, d - w)) / np.maximum(
            w * w, 1e-30)
    return np.clip(np.where(w > COVER_TENT_MIN * f.rho, tent, ring_fence_g(f, d)), 0.0, 1.0)


def ring_fence_mean(f: Fence) -> float:
    """g's mean over the ring's width (|u| < rho): how much of what lies inside its silhouette it hides."""
    return float(np.clip((f.g1s + f.rho - f.ys) / max(f.rho, 1e-30), 0.0, 1.0))


def medium_weight(wu, fibers: int, rings: int):
    """0 (scan the fibers) .. 1 (a medium), by the fiber slots the footprint (half-width wu) spans on a mean
    ring, fibers / rings slots around radius 1/2: GLSL smoothstep(COVER_MEDIUM_FROM, COVER_MEDIUM_FULL, .)."""
    x = 2.0 * np.asarray(wu, np.float64) * fibers / (math.pi * max(rings, 1))
    t = np.clip((x - COVER_MEDIUM_FROM) / (COVER_MEDIUM_FULL - COVER_MEDIUM_FROM), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def exp_mean(k: float, p0, p1, e0=None, e1=None):
    """The mean of exp(-k p) for p running linearly from p0 to p1 (e0, e1: exp(-k p0), exp(-k p1))."""
    p0, p1 = np.asarray(p0, np.float64), np.asarray(p1, np.float64)
    e0 = np.exp(-k * p0) if e0 is None else e0
    e1 = np.exp(-k * p1) if e1 is None else e1
    spread = k * np.abs(p1 - p0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(spread > 1e-3, np.abs(e0 - e1) / spread, 0.5 * (e0 + e1))


def medium_alpha(lay: RingLayout, d, w, present=1.0, scale: float = 1.0):
    """A container's coverage of a tent footprint as the medium composites it (coverage.glsl: cover_medium,
    cover_container's rescale at COVER_OPAQUE): per ring both arcs' fence cover, each under what the front
    arcs of its own and the outer rings leave open (their fences' means); a back arc under the back arcs
    inside it too.
    ``present``: the share of every arc's fibers inside the container's window and alive (1: all);
    ``scale``: the ellipsoid's factor on every ring's radius. A ring's fence has its fibers' outer side as
    its edge (rho + rf): their centres' jitter spreads the silhouette both ways about it."""
    d, w = np.broadcast_arrays(np.asarray(d, np.float64), np.asarray(w, np.float64))
    front = np.zeros(d.shape)
    back = np.zeros(d.shape)
    opened = np.ones(d.shape)
    for i in range(lay.rings):
        rf = float(lay.ring_radius[i])
        f = ring_fence(scale * float(lay.rho[i]) + rf, float(lay.n[i]), rf)       # the fibers' outer side
        cover, hides = ring_fence_cover(f, d, w), ring_fence_mean(f)
        front = front + cover * present * opened
        opened = opened * (1.0 - hides * present)
        back = back * (1.0 - hides * present) + cover * present * opened
    total = front + back
    total = total / np.maximum(total, 1.0)
    return 1.0 - np.maximum((1.0 - total) - COVER_OPAQUE, 0.0) / (1.0 - COVER_OPAQUE)


def cover_light_path(q, l2):
    """The distance from q (a point of a container's cross-section, unit space) to the unit circle along a
    direction whose xy part is l2 (the key light: its path in 3D for a unit direction); inf along the
    axis (coverage.glsl: cover_light_path)."""
    q, l2 = np.asarray(q, np.float64), np.asarray(l2, np.float64)
    ll = (l2 * l2).sum(-1)
    qb = (q * l2).sum(-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        root = np.sqrt(np.maximum(qb * qb - ll * ((q * q).sum(-1) - 1.0), 0.0))
        return np.where(ll > 0.0, (-qb + root) / np.where(ll > 0.0, ll, 1.0), np.inf)


def medium_face(rho: float, n: float, rf: float, dr: float) -> tuple[float, float, float]:
    """Where a footprint's rays first meet a ring's fibers, for the medium's light and occlusion
    (coverage.glsl: medium_face). Where fibers do not overlap (k = n rf / (pi rho) fiber widths over each
    point of the ring, k <= 1) a ray meets one fiber on its side facing the ray, its centre on the ring;
    where many overlap, the outermost of them on its outer side, its centre out by the largest of k radial
    jitters uniform in +-dr, dr (k - 1) / (k + 1); in between both by q = (k - 1) / (k + 1). Returns (the
    first fibers' centre radius, the radius of the circle the light is taken on, the share 1 - q of the
    facing side's offset, -rf along the ray, kept)."""
    k = n * rf / (np.pi * max(rho, 1e-30))
    q = max(k - 1.0, 0.0) / (k + 1.0)
    centre = rho + q * q * dr
    return centre, centre + q * rf, 1.0 - q


def medium_arc_light(lay: RingLayout, i: int, d, w, l2, sigma: float, scale: float = 1.0):
    """The key light's density-estimate transmittance the medium gives ring i's (front, back) arcs
    (coverage.glsl: cover_medium's light nodes): the path to the wall taken piecewise linear in the angle
    between COVER_LIGHT_NODES points over the footprint's share (+-w / sqrt 2 about the centre line at d)
    of the circle medium_face gives, shifted towards the ray by its kept share of the fibers' radius (the
    back arc's at the same angles on the circle mirrored about rho), exp averaged exactly per piece and
    weighted by its width across the footprint. The view looks along +x of the cross-section, the centre
    line at y = d; l2: the light's xy part in that frame; scale: the ellipsoid's factor on the ring's radius
    and jitter."""
    rho = scale * float(lay.rho[i])
    rf = float(lay.ring_radius[i])
    _, face, keep = medium_face(rho, float(lay.n[i]), rf, scale * float(lay.max_dr[i]))
    back = max(2.0 * rho - face, 0.0) / face
    l2 = np.asarray(l2, np.float64)
    phis = np.linspace(np.arcsin(np.clip((d - 0.70710678 * w) / face, -1, 1)),
                       np.arcsin(np.clip((d + 0.70710678 * w) / face, -1, 1)), COVER_LIGHT_NODES)
    ys = face * np.sin(phis)
    xs = face * np.cos(phis)
    shift = -keep * rf
    paths = [np.maximum([cover_light_path(np.array([-x + shift, y]), l2),
                         cover_light_path(np.array([back * x + shift, back * y]), l2)], 0.0)
             for x, y in zip(xs, ys)]
    es = [np.exp(-sigma * np.minimum(p, 1e6)) for p in paths]
    spread = ys[-1] - ys[0]
    if spread <= 0.0:
        return es[-1]
    light = sum((ys[k] - ys[k - 1]) * exp_mean(sigma, paths[k - 1], paths[k], es[k - 1], es[k])
                for k in range(1, COVER_LIGHT_NODES))
    return light / spread
