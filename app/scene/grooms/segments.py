"""Segment count: how many straight pieces a groom's guides get, chosen per groom so that the guides stay
close to the strands they stand for and no joint folds too sharply (see :func:`auto_segments`)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from .guides import _CHUNK_ELEMS, _point_polyline_distance, resample_many

SEGMENT_TOLERANCE = 0.5
"""Automatic segment count: the guide may leave the strand it stands for by at most this fraction of the
container radius, for 95 % of strands. Below one radius the strand stays inside its own fiber cloud; half a
radius keeps it off the rim, where a container's outer ring is all that covers it."""

MAX_TURN_DEG = 120.0
"""Automatic segment count: no joint of any guide may turn by more than this. Neighbouring containers meet
on the bisecting (miter) plane, which leans ``radius * tan(turn / 2)`` past the joint: 1.7 radii at 120
degrees, but 8.6 radii at Curly_100's 167-degree fold with 3 segments, a wedge of fibers far from any
strand. Finer guides turn less per joint."""

_AUTO_SEGMENTS = (1, 2, 3, 4, 5, 6, 8, 10, 12, 16, 20, 24, 32, 40, 48, 64)
_AUTO_SAMPLE_VERTICES = 1 << 14     # strand vertices measured per candidate count: bounds the auto search
_ROW_CHUNK = 1 << 16                # guides resampled and checked per vectorised step


def chord_errors(polylines: Sequence[np.ndarray], n_segments: int) -> np.ndarray:
    """How far each polyline's vertices get from the polyline resampled to ``n_segments``: (len,) maxima."""
    res = resample_many(polylines, n_segments)
    counts = np.fromiter((len(q) for q in polylines), np.int64, len(polylines))
    pts = np.concatenate([np.asarray(q, np.float64) for q in polylines])
    sid = np.repeat(np.arange(len(polylines)), counts)
    out = np.zeros(len(polylines))
    step = max(1, _CHUNK_ELEMS // (4 * (n_segments + 1)))
    for a in range(0, len(pts), step):
        d = _point_polyline_distance(pts[a:a + step, None], res[sid[a:a + step]])[:, 0]
        np.maximum.at(out, sid[a:a + step], d)
    return out


def joint_turns(guides: np.ndarray) -> np.ndarray:
    """Turn angle in degrees at every inner joint of guides (S, M, 3): (S, M - 2)."""
    d = np.diff(guides, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        d = d / np.linalg.norm(d, axis=2, keepdims=True)
        c = np.nan_to_num((d[:, 1:] * d[:, :-1]).sum(axis=2), nan=1.0)
    return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))


def fold_fraction(guides: np.ndarray, radii) -> float:
    """Share of the inner joints of guides (S, M, 3) with root radii ``radii`` where the container's fibers
    fold back: a fiber on the inside of a joint that turns by theta, at the radius r from the axis, loses
    r tan(theta / 2) of each neighbouring piece to the bisecting plane, so where that is more than half the
    shorter piece it runs backwards (the discrete form of a radius past the radius of curvature: Curly_100's
    balls and shells). 0 with no inner joint."""
    guides = np.asarray(guides, np.float64)
    if guides.shape[1] < 3 or len(guides) == 0:
        return 0.0
    d = np.diff(guides, axis=1)
    h = np.linalg.norm(d, axis=2)
    turn = np.radians(joint_turns(guides))
    r = np.broadcast_to(np.asarray(radii, np.float64).reshape(-1, 1), turn.shape)
    folds = r * np.tan(np.minimum(turn, np.radians(179.9)) / 2) > 0.5 * np.minimum(h[:, 1:], h[:, :-1])
    return float(folds.mean())


def _joints_ok(polylines: Sequence[np.ndarray], n_segments: int) -> bool:
    """Every guide resampled to ``n_segments`` has pieces of non-zero length (a strand that comes back to
    where it was cannot be a container there) and joints within :data:`MAX_TURN_DEG`. In chunks of guides,
    stopping at the first failure, so the search stays within bounded memory on any groom."""
    for a in range(0, len(polylines), _ROW_CHUNK):
        guides = resample_many(polylines[a:a + _ROW_CHUNK], n_segments)
        if not (np.linalg.norm(np.diff(guides, axis=1), axis=2) > 0).all():
            return False
        if n_segments > 1 and joint_turns(guides).max() > MAX_TURN_DEG:
            return False
    return True


def auto_segments(polylines: Sequence[np.ndarray], radii: np.ndarray, seed: int = 0) -> tuple[int, float, str]:
    """(segments, p95 error in radii, reason): the fewest segments in ``_AUTO_SEGMENTS`` whose resampled
    guides stay within :data:`SEGMENT_TOLERANCE` radii of the polylines they replace (95th percentile over
    a seeded sample) and turn by at most :data:`MAX_TURN_DEG` at every joint (all guides). Never more than
    the polylines' own segment count (more cannot follow them closer) nor 64; when no count meets both,
    that cap.
    """
    counts = np.fromiter((len(q) for q in polylines), np.int64, len(polylines))
    cap = int(min(64, max(1, counts.max() - 1)))
    order = np.random.default_rng(seed).permutation(len(polylines))
    take = order[: max(1, int(np.searchsorted(np.cumsum(counts[order]), _AUTO_SAMPLE_VERTICES, "right")))]
    sample = [polylines[i] for i in take]
    r = np.asarray(radii, np.float64)[take]
    p95 = math.inf
    for n in [c for c in _AUTO_SEGMENTS if c < cap] + [cap]:
        p95 = float(np.percentile(chord_errors(sample, n) / r, 95))
        if p95 > SEGMENT_TOLERANCE:
            continue
        if _joints_ok(polylines, n):
            return n, p95, (f"auto: the fewest that keep 95% of {len(sample):,} sampled strands within "
                            f"{SEGMENT_TOLERANCE} radii of their guide and every joint within {MAX_TURN_DEG:g} "
                            f"degrees")
    return cap, p95, (f"auto: no count up to the strands' own {cap} keeps them within {SEGMENT_TOLERANCE} "
                      f"radii of their guide and every joint within {MAX_TURN_DEG:g} degrees, so {cap}")
