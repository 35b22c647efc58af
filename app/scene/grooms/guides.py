"""Guides: strands resampled to equal arc-length pieces, one guide per strand or one per k-means cluster of
strands, and the container radius each guide gets (root spacing; clusters: enough for their members).

Memory stays bounded whatever the groom size: every vectorised step creates at most ``_CHUNK_ELEMS``
float64 elements.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from .groom import Groom, GroomError

# Bound on the float64 elements one vectorised step may create at once (2 MiB), so clustering and nearest-
# neighbour searches on 100k+ strands stay in bounded memory whatever the groom size; chunks this small also
# stay in cache, which measured 7x faster than 32 MiB chunks on harolongo's roots.
_CHUNK_ELEMS = 1 << 18
SPACING_CLIP = (0.5, 2.0)      # a root disc's radius: the root's nearest-neighbour distance, x median, clipped


def resample_many(strands: Sequence[np.ndarray], n_segments: int) -> np.ndarray:
    """Resample every strand to ``n_segments`` pieces equally spaced in arc length: (S, n_segments + 1, 3).

    All strands go through one ``np.interp`` per coordinate: strand i is parametrised on [2i, 2i + 1], so the
    parameter stays strictly increasing across strands and the gaps keep neighbours from blending.
    """
    if n_segments < 1:
        raise ValueError(f"n_segments must be >= 1, not {n_segments}")
    n = len(strands)
    if n == 0:
        return np.zeros((0, n_segments + 1, 3))
    counts = np.fromiter((len(s) for s in strands), np.int64, n)
    if (counts < 2).any():
        raise ValueError("every strand needs at least 2 vertices to be resampled")
    pts = np.concatenate([np.asarray(s, np.float64).reshape(-1, 3) for s in strands])
    sid = np.repeat(np.arange(n, dtype=np.int64), counts)
    ends = np.cumsum(counts)
    starts = ends - counts
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    seg[ends[:-1] - 1] = 0.0                        # the jump from one strand's tip to the next root
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    total = cum[ends - 1] - cum[starts]
    if not (total > 0).all():
        raise ValueError(f"strand {int(np.argmin(total > 0))} has zero length and cannot be resampled")
    # Clipping keeps t non-decreasing within a strand despite rounding in cum / total; np.interp then needs
    # it strictly increasing, so only the first vertex of each run of equal t (duplicates) is used. Strand i
    # lives on [2i, 2i + 1], which keeps the whole sequence increasing and neighbours from blending.
    t = np.minimum((cum - cum[starts][sid]) / total[sid], 1.0)
    t[ends - 1] = 1.0
    use = np.ones(len(t), bool)
    use[1:] = t[1:] > t[:-1]
    use[starts] = True
    kt = t[use] + 2.0 * sid[use]
    kp = pts[use]
    q = (2.0 * np.arange(n)[:, None] + np.linspace(0.0, 1.0, n_segments + 1)[None, :]).ravel()
    out = np.empty((n * (n_segments + 1), 3))
    for c in range(3):
        out[:, c] = np.interp(q, kt, kp[:, c])
    out = out.reshape(n, n_segments + 1, 3)
    out[:, 0] = pts[starts]
    out[:, -1] = pts[ends - 1]
    return out


def resample(strand: np.ndarray, n_segments: int) -> np.ndarray:
    """One strand resampled to ``n_segments`` equal arc-length pieces: (n_segments + 1, 3), same endpoints."""
    return resample_many([strand], n_segments)[0]


def _nearest_distances(points: np.ndarray, queries: np.ndarray, exclude: np.ndarray, tiny: float) -> np.ndarray:
    """Distance from each query to its nearest point other than itself (and other than exact duplicates,
    closer than ``tiny``: two strands sharing a root say nothing about spacing). Chunked brute force."""
    out = np.empty(len(queries))
    p2 = (points**2).sum(axis=1)
    step = max(1, _CHUNK_ELEMS // max(len(points), 1))
    for a in range(0, len(queries), step):
        q = queries[a:a + step]
        d2 = (q**2).sum(axis=1)[:, None] - 2.0 * q @ points.T + p2[None, :]
        d2[np.arange(len(q)), exclude[a:a + step]] = np.inf
        d2[d2 <= tiny * tiny] = np.inf
        out[a:a + step] = np.sqrt(np.maximum(d2.min(axis=1), 0.0))
    return out


def nearest_points(points: np.ndarray, queries: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """(indices, distances) of each query's ``k`` nearest points, nearest first; chunked brute force."""
    k = min(k, len(points))
    idx = np.empty((len(queries), k), np.int64)
    dist = np.empty((len(queries), k))
    p2 = (points ** 2).sum(axis=1)
    step = max(1, _CHUNK_ELEMS // max(1, len(points)))
    for a in range(0, len(queries), step):
        q = queries[a:a + step]
        d2 = np.maximum((q ** 2).sum(axis=1)[:, None] - 2.0 * q @ points.T + p2[None, :], 0.0)
        part = np.argpartition(d2, k - 1, axis=1)[:, :k] if k < len(points) else np.tile(np.arange(k), (len(q), 1))
        pd = np.take_along_axis(d2, part, 1)
        order = np.argsort(pd, axis=1, kind="stable")
        idx[a:a + step] = np.take_along_axis(part, order, 1)
        dist[a:a + step] = np.sqrt(np.take_along_axis(pd, order, 1))
    return idx, dist


def root_spacing(roots: np.ndarray) -> np.ndarray:
    """Each root's distance to its nearest other root (duplicates skipped), clipped to ``SPACING_CLIP`` x
    the median: the radius over which a guide's children (and the looks bench's reference strands) are
    spread. Without two distinct roots there is no spacing to read: 1e-3 of the roots' extent (or 1e-3)."""
    roots = np.asarray(roots, np.float64)
    S = len(roots)
    size = float(np.ptp(roots, axis=0).max()) if S else 0.0
    if S < 2 or size <= 0.0:
        return np.full(S, 1e-3 * max(size, 1.0))
    _, dist = nearest_points(roots, roots, min(S, 8))
    dist = np.where(dist > 1e-9 * size, dist, np.inf)
    nn = dist.min(axis=1)
    finite = np.isfinite(nn)
    m = float(np.median(nn[finite])) if finite.any() else 1e-3 * size
    return np.clip(np.where(finite, nn, m), SPACING_CLIP[0] * m, SPACING_CLIP[1] * m)


def default_radius(roots: np.ndarray, seed: int = 0, max_queries: int = 1024) -> float:
    """Container radius from root spacing: 0.75 x the median distance from a root to its nearest neighbour,
    so neighbouring cylinders overlap a little and the scalp is covered without gaps.

    The median comes from at most ``max_queries`` seeded sample roots against all roots, which bounds time
    and memory for very large grooms while staying a stable estimate. Falls back to 0.5 % of the root spread
    (or 1.0 for a single root at the origin of nothing) when no two distinct roots exist.
    """
    roots = np.asarray(roots, np.float64).reshape(-1, 3)
    n = len(roots)
    spread = float(np.linalg.norm(roots.max(axis=0) - roots.min(axis=0))) if n else 0.0
    fallback = 0.005 * spread if spread > 0 else 1.0
    if n < 2:
        return fallback
    rng = np.random.default_rng(seed)
    idx = np.arange(n) if n <= max_queries else np.sort(rng.choice(n, max_queries, replace=False))
    d = _nearest_distances(roots, roots[idx], idx, 1e-9 * spread)
    d = d[np.isfinite(d)]
    return 0.75 * float(np.median(d)) if len(d) else fallback


def _kmeans(x: np.ndarray, k: int, seed: int, max_iter: int = 50) -> np.ndarray:
    """Seeded k-means (k-means++ start when affordable) returning a label per row, in bounded memory."""
    n = len(x)
    rng = np.random.default_rng(seed)
    x2 = (x**2).sum(axis=1)

    def dist2_to(c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        labels = np.empty(n, np.int64)
        best = np.empty(n)
        c2 = (c**2).sum(axis=1)
        step = max(1, _CHUNK_ELEMS // max(len(c), 1))
        for a in range(0, n, step):
            d2 = x2[a:a + step, None] - 2.0 * x[a:a + step] @ c.T + c2[None, :]
            labels[a:a + step] = d2.argmin(axis=1)
            best[a:a + step] = d2[np.arange(len(d2)), labels[a:a + step]]
        return labels, np.maximum(best, 0.0)

    if n * k <= 50_000_000:
        # k-means++: spread the starting centres so small, far clusters (a stray lock) get their own guide.
        centres = np.empty((k, x.shape[1]))
        centres[0] = x[rng.integers(n)]
        d2 = ((x - centres[0]) ** 2).sum(axis=1)
        for j in range(1, k):
            s = d2.sum()
            i = int(rng.choice(n, p=d2 / s)) if s > 0 else int(rng.integers(n))
            centres[j] = x[i]
            d2 = np.minimum(d2, ((x - x[i]) ** 2).sum(axis=1))
    else:
        centres = x[rng.choice(n, k, replace=False)].copy()
    labels = np.full(n, -1, np.int64)
    for _ in range(max_iter):
        new, best = dist2_to(centres)
        if np.array_equal(new, labels):
            break
        labels = new
        sizes = np.bincount(labels, minlength=k)
        for c in range(x.shape[1]):
            centres[:, c] = np.bincount(labels, weights=x[:, c], minlength=k)
        empty = sizes == 0
        centres[~empty] /= sizes[~empty, None]
        if empty.any():
            # Re-seed an empty cluster at the worst-fitting strands so k guides really are made.
            far = np.argsort(best)[::-1][: int(empty.sum())]
            centres[empty] = x[far]
            labels[far] = np.flatnonzero(empty)
    return labels


def _point_polyline_distance(p: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Distances from points p (M, P, 3) to polylines poly (M, Q, 3): (M, P)."""
    a, b = poly[:, None, :-1], poly[:, None, 1:]             # (M, 1, Q-1, 3)
    ab = b - a
    ap = p[:, :, None, :] - a                                  # (M, P, Q-1, 3)
    denom = np.maximum((ab**2).sum(axis=-1), 1e-300)
    t = np.clip((ap * ab).sum(axis=-1) / denom, 0.0, 1.0)
    d = np.linalg.norm(ap - t[..., None] * ab, axis=-1)
    return d.min(axis=-1)


class Guides(tuple):
    """``(polylines, radii)`` — unpacks like a pair — plus ``dropped`` (reason -> strand count) and
    ``labels`` (guide index of every groom strand, -1 where the strand was dropped)."""

    dropped: dict[str, int]
    labels: np.ndarray

    def __new__(cls, polylines: list[np.ndarray], radii: np.ndarray, dropped: dict[str, int],
                labels: np.ndarray) -> Guides:
        self = super().__new__(cls, (polylines, radii))
        self.dropped = dropped
        self.labels = labels
        return self

    @property
    def polylines(self) -> list[np.ndarray]:
        return self[0]

    @property
    def radii(self) -> np.ndarray:
        return self[1]


def strands_to_guides(groom: Groom, segments: int = 8, radius: float | None = None, cluster: int = 0,
                      seed: int = 0, min_length: float | None = None) -> Guides:
    """Guide polylines (each ``segments + 1`` points) and one container radius per guide.

    ``cluster=0``: every strand is a guide and every radius is ``radius`` or :func:`default_radius` of the
    roots. ``cluster=N``: N guides from k-means over resampled strands; a guide is its cluster's mean strand
    and its radius covers 90 % of the members (each member's farthest point from the guide), never less
    than ``radius`` or the default.

    Strands shorter than ``min_length`` (default 1e-3 of the groom's bbox diagonal: sub-pixel whenever the
    whole groom is in view, so a container there is only a blob) are dropped and counted.
    """
    if segments < 1:
        raise ValueError(f"segments must be >= 1, not {segments}")
    if cluster < 0:
        raise ValueError(f"cluster must be >= 0, not {cluster}")
    if radius is not None and not (math.isfinite(radius) and radius > 0):
        raise ValueError(f"radius must be a finite number > 0, not {radius!r}")
    lo, hi = groom.bbox()
    diag = float(np.linalg.norm(hi - lo))
    if min_length is None:
        min_length = 1e-3 * diag
    lengths = groom.lengths()
    keep = lengths >= min_length
    dropped = {"shorter than min_length": int((~keep).sum())} if not keep.all() else {}
    if not keep.any():
        raise GroomError(f"{groom.path.name}: no strand is at least {min_length:g} long")
    kept = [s for s, k in zip(groom.strands, keep) if k]
    res = resample_many(kept, segments)
    floor = float(radius) if radius is not None else default_radius(res[:, 0], seed=seed)
    labels = np.full(groom.n_strands, -1, np.int64)
    kept_idx = np.flatnonzero(keep)
    if cluster == 0 or cluster >= len(kept):
        labels[kept_idx] = np.arange(len(kept))
        return Guides(list(res), np.full(len(kept), floor), dropped, labels)

    n, m = res.shape[0], res.shape[1]
    # Features are the whole resampled strand, so the cluster mean *is* the mean strand; the root is weighted
    # to count as much as the rest of the strand together, keeping each guide anchored where its members grow.
    w = np.ones((m, 1))
    w[0] = math.sqrt(m)
    feats = (res * w).reshape(n, -1)
    lab = _kmeans(feats, cluster, seed)
    sizes = np.bincount(lab, minlength=cluster)
    guides = np.empty((cluster, m, 3))
    for c in range(3):
        flat = res[:, :, c]
        for j in range(m):
            guides[:, j, c] = np.bincount(lab, weights=flat[:, j], minlength=cluster)
    guides /= np.maximum(sizes, 1)[:, None, None]
    # Each member's farthest point from its guide polyline; chunked so (members x points x segments) stays small.
    far = np.empty(n)
    step = max(1, _CHUNK_ELEMS // (m * m * 3))
    for a in range(0, n, step):
        far[a:a + step] = _point_polyline_distance(res[a:a + step], guides[lab[a:a + step]]).max(axis=1)
    order = np.lexsort((far, lab))
    sorted_far = far[order]
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    pos = starts + 0.9 * np.maximum(sizes - 1, 0)
    lo_i = np.floor(pos).astype(np.int64)
    hi_i = np.minimum(lo_i + 1, starts + np.maximum(sizes - 1, 0))
    frac = pos - lo_i
    safe = sizes > 0
    p90 = np.zeros(cluster)
    p90[safe] = (sorted_far[lo_i[safe]] * (1 - frac[safe]) + sorted_far[hi_i[safe]] * frac[safe])
    radii = np.maximum(p90, floor)
    # k-means re-seeds empty clusters, but a cluster can still end empty when strands coincide exactly.
    used = np.flatnonzero(sizes > 0)
    remap = np.full(cluster, -1, np.int64)
    remap[used] = np.arange(len(used))
    labels[kept_idx] = remap[lab]
    return Guides(list(guides[used]), radii[used], dropped, labels)
