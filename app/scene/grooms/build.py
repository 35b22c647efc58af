"""A groom's scene: guides (one per strand or per cluster) resampled to a segment count and turned into
containers by ``Scene.from_polylines``, the one builder of container rows, plus the facts of the source that
``vfiber info`` reports (:class:`~app.scene.groom_info.GroomScene`)."""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ...params import Params
from .. import containers
from . import children
from ..containers import Scene
from .groom import Groom, GroomError, guide_colors
from .guides import resample_many, strands_to_guides
from .load import load_groom
from .segments import MAX_TURN_DEG, auto_segments, chord_errors, joint_turns

if TYPE_CHECKING:
    from ..groom_info import GroomScene

def _scene_rows(guides: np.ndarray, radii: np.ndarray, taper: float, name: str) -> tuple[np.ndarray, np.ndarray]:
    """float32 container rows (``Scene.from_polylines``) and the float64 origin for guides (S, M, 3), or a
    :class:`GroomError` when no container is left or the rows do not fit float32."""
    lo, hi = guides.reshape(-1, 3).min(axis=0), guides.reshape(-1, 3).max(axis=0)
    origin = 0.5 * (lo + hi)
    M = guides.shape[1]
    with np.errstate(over="ignore", invalid="ignore"):   # far coordinates are reported below, not warned
        rows = Scene.from_polylines(guides, radii, taper=taper, origin=origin).segments
    if len(rows) == 0:
        raise GroomError(f"{name}: no usable strands: every guide comes back to its root at {M - 1} segments, "
                         f"so no container is left; set scene.segments higher")
    if not np.isfinite(rows).all():
        raise GroomError(f"{name}: coordinates are too large for the renderer's float32 containers after "
                         f"centring (extent {np.round(hi - lo, 3).tolist()}); check scene.groom_scale")
    return rows, origin


def groom_scene(groom: Groom, p: Params, seconds: dict[str, float] | None = None) -> GroomScene:
    """Containers for a loaded groom under parameters ``p`` (see :func:`scene_from_groom`)."""
    from ..groom_info import GroomScene, GroomSource

    name = groom.path.name
    seconds = dict(seconds or {})
    t0 = time.perf_counter()
    given = p["scene.segments"] if p["scene.segments"] > 1 else None
    cluster = p["scene.groom_cluster"]
    try:
        # Drops and the root-spacing radius; one segment is the cheapest resampling that yields them.
        base = strands_to_guides(groom, 1, seed=p["scene.seed"])
    except GroomError as exc:
        raise GroomError(f"{name}: no usable strands: {str(exc).split(': ', 1)[-1]}") from None
    kept = np.flatnonzero(base.labels >= 0)
    floor = float(base.radii[0])
    radius_reason = "0.75 x the median distance between neighbouring roots"
    if cluster and cluster < len(kept):
        # Cluster at the strands' own resolution; the guides are then resampled like strands would be.
        counts = np.fromiter((len(groom.strands[i]) for i in kept), np.int64, len(kept))
        fine_n = int(min(64, counts.max() - 1))
        guides = strands_to_guides(groom, fine_n, cluster=cluster, seed=p["scene.seed"])
        fine, radii = list(guides.polylines), np.asarray(guides.radii)
        radius_reason = f"covers 90% of each cluster's strands, at least the root-spacing radius {floor:.4g}"
        cluster_used = cluster
        labels = guides.labels
    else:
        fine, radii = [groom.strands[i] for i in kept], np.full(len(kept), floor)
        cluster_used = 0
        labels = base.labels
    # The clump size: a scale of the groom's own radius, not scene.radius (the generators' radius in world
    # units), because one number in units cannot suit grooms whose root spacings differ 7,000-fold
    # (Ratboy 0.0026, Bangs 18); scaled before the segment count, whose tolerance is in radii.
    scale = p["scene.groom_radius_scale"]
    if scale != 1.0:
        radii = radii * scale
        radius_reason = f"{scale:g} x ({radius_reason}): scene.groom_radius_scale"
    per_guide = p["scene.groom_children"]
    grown = None
    if per_guide:
        # thinner containers between the strands (children.py), blended on one arc-length parameter; the
        # segment count is still the guides' (a blend's cusp is the blend's, not the groom's)
        grown = children.with_children(children.common_parameter(fine), per_guide, seed=p["scene.seed"])
        radii = radii * grown.narrow
        fine = list(grown.polylines[:len(fine)])
        radius_reason = (f"{grown.narrow:.3g} x ({radius_reason}): 1 / sqrt(1 + {per_guide}), a guide and its "
                         f"{per_guide} interpolated children share one container's cross-section "
                         f"(scene.groom_children)")
    taper = p["scene.taper"]
    radius_reason += (f"; the tip radius is {1.0 - taper:g} x the root's (scene.taper = {taper:g})" if taper
                      else "; scene.radius is the generators' (grooms scale theirs with scene.groom_radius_scale)")
    guides_total = len(fine) if grown is None else len(grown.polylines)
    if guides_total > containers.MAX_GUIDES:
        raise GroomError(f"{name}: {guides_total:,} guides is more than the renderer's {containers.MAX_GUIDES:,}; "
                         f"set scene.groom_cluster to make fewer")
    if given:
        n = given
        p95 = float(np.percentile(chord_errors(fine, n) / radii, 95))
        reason = f"scene.segments = {n}"
    else:
        n, p95, reason = auto_segments(fine, radii, seed=p["scene.seed"])
        reason += " (scene.segments = 1 means auto for grooms)"
    # Polylines that already have n segments are used as they are: resampling could only move their points.
    same = all(len(q) == n + 1 for q in fine)
    polylines = np.stack(fine) if same else resample_many(fine, n)
    if same:
        p95 = 0.0
    native = same and not cluster_used and grown is None      # the guides are the file's own vertices
    warnings = list(groom.warnings)
    parents = np.arange(len(polylines))
    if grown is not None:
        kids = grown.polylines[len(fine):]
        polylines = np.concatenate([polylines, kids if kids.shape[1] == n + 1 else resample_many(list(kids), n)])
        polylines, unfolded = grown.settle(polylines, MAX_TURN_DEG)
        parents = grown.parents
        radii = radii[parents]
        if unfolded:
            warnings.append(f"{unfolded:,} of {len(kids):,} interpolated children fold at {n} segments (their "
                            f"blend turns past {MAX_TURN_DEG:g} degrees): each takes its nearest strand's shape")
    folded = int((~(np.linalg.norm(np.diff(polylines, axis=1), axis=2) > 0).all(axis=1)).sum())
    if folded:
        warnings.append(f"{folded:,} guides have a zero-length piece at {n} segments (a strand that comes back "
                        f"to where it was); those pieces make no container")
    turns = joint_turns(polylines)
    sharp = int((turns > MAX_TURN_DEG).sum())
    if sharp:
        lean = math.tan(math.radians(min(float(turns.max()), 179.0)) / 2)
        warnings.append(f"{sharp:,} joints turn by more than {MAX_TURN_DEG:g} degrees (up to {turns.max():.0f}); "
                        f"their containers lean up to {lean:.1f} radii past the joint")
    seconds["guides"] = time.perf_counter() - t0
    t1 = time.perf_counter()
    rows, origin = _scene_rows(polylines, radii, p["scene.taper"], name)
    seconds["containers"] = time.perf_counter() - t1
    dropped = dict(base.dropped)
    source = GroomSource(
        path=groom.path, format=groom.format, strands_in_file=groom.n_strands + sum(groom.skipped.values()),
        strands=groom.n_strands, vertices=groom.n_vertices, skipped=dict(groom.skipped), dropped=dropped,
        up=groom.up, up_reason=groom.up_reason, scale=groom.scale, bbox=groom.bbox(), cluster=cluster_used,
        cluster_requested=cluster,
        guides=len(polylines), segments=n, segments_reason=reason, native=native, chord_p95=p95,
        radius_reason=radius_reason, radii=radii, children=per_guide, seconds=seconds, warnings=warnings,
        max_turn=float(turns.max()) if turns.size else 0.0)
    colors = guide_colors(groom, labels, int(parents.max()) + 1 if len(parents) else 0)
    return GroomScene(rows, origin, groom.path.stem, len(polylines), None if colors is None else colors[parents],
                      source=source, params=p)


def scene_from_groom(p: Params) -> GroomScene:
    """The scene of ``scene.groom_file``: load (``scene.groom_up``, ``scene.groom_scale``), build guides
    (``scene.groom_cluster``, ``scene.segments``, ``scene.seed``) and containers (``scene.taper``).

    Guides: one per strand, or ``scene.groom_cluster`` k-means clusters of strands (the thesis's hybrid: few
    thick containers, many fibers each). Segments: ``scene.segments`` when it is more than 1; at 1, the
    default, it is chosen per groom (:func:`auto_segments`), because one straight segment from root to tip
    never contains a real strand. Guides are the file's own vertices whenever every strand already has
    exactly that many segments. Radius: from root spacing (clusters: enough for their members), times
    ``scene.groom_radius_scale``; ``scene.radius`` is the generators' and is not used. ``scene.taper``
    narrows every container toward the tip as for the generators (tighter clumps at the tips). Raises
    :class:`GroomError` for anything wrong with the file, including a file without one usable strand.
    """
    t0 = time.perf_counter()
    groom = groom_of(p)
    return groom_scene(groom, p, {"load": time.perf_counter() - t0})


def groom_of(p: Params) -> Groom:
    """``scene.groom_file`` loaded under ``p`` (``scene.groom_up``, ``scene.groom_scale``); a
    :class:`GroomError` names the whole path, as a person gave it."""
    path = Path(p["scene.groom_file"])
    try:
        return load_groom(path, up=p["scene.groom_up"], scale=p["scene.groom_scale"])
    except GroomError as exc:  # the loaders name the file by its base name; a person needs the whole path
        text = str(exc)
        if text.startswith(f"{path.name}:") and str(path) != path.name:
            raise GroomError(f"{path}{text[len(path.name):]}") from None
        raise
