"""A scene built from a groom file, and what ``vfiber info`` says about it.

``GroomScene`` is a :class:`~app.scene.containers.Scene` (containers only, nothing per fiber) that also
remembers the facts of its source: how many strands and vertices the file held, what was skipped or dropped
and why, which axis was taken as up and why, how the guides were made. ``source_info()`` turns those facts
and the parameters the scene was built with into the lines ``vfiber info`` prints after its own.

The GPU byte lines are the renderers' figures, which the scene layer cannot know (it sits before the
renderer): ``app.info`` computes them and hands them in.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..params import Params
from .containers import Scene

_W = 17  # label column width, as in ``app.info.info_lines``


@dataclass
class GroomSource:
    """Facts about the file and the guides made from it (all counts are strands unless named)."""

    path: Path
    format: str
    strands_in_file: int               # loaded + skipped
    strands: int                       # loaded (usable)
    vertices: int                      # of the loaded strands
    skipped: dict[str, int]            # by the loader, reason -> count
    dropped: dict[str, int]            # by the guide builder, reason -> count
    up: str
    up_reason: str
    scale: float
    bbox: tuple[np.ndarray, np.ndarray]   # strands, world units (rotated and scaled)
    cluster: int                       # clusters made; 0 = one guide per strand
    cluster_requested: int             # scene.groom_cluster (0, or at least as many as strands: one per strand)
    guides: int
    segments: int                      # container segments per guide
    segments_reason: str
    native: bool                       # the guides are the file's own vertices (no resampling)
    chord_p95: float                   # 95th percentile of how far strands leave their guide, in radii
    max_turn: float                    # sharpest joint of any guide, degrees
    radius_reason: str
    radii: np.ndarray                  # root radius per guide
    children: int = 0                  # interpolated children per guide (scene.groom_children)
    seconds: dict[str, float] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)


@dataclass(eq=False)
class GroomScene(Scene):
    """Containers made from a groom file, plus where they came from."""

    source: GroomSource | None = None
    params: Params | None = None

    def source_info(self, p: Params | None = None, gpu_lines: Sequence[str] = ()) -> list[str]:
        """Lines for ``vfiber info``; fiber counts follow ``p`` (default: the build parameters), so a viewer
        that changes ``fibers.*`` without rebuilding the scene can pass its current ones. ``gpu_lines`` (from
        ``app.info.gpu_lines``) go after the fiber count."""
        return source_info(self, p or self.params or Params({}), gpu_lines)


def _count(d: dict[str, int]) -> str:
    return ", ".join(f"{n:,} {why}" for why, n in d.items()) if d else "none"


def source_info(scene: Scene, p: Params, gpu_lines: Sequence[str] = ()) -> list[str]:
    """Lines for ``vfiber info``: the file, what was kept, orientation, guides, fibers, then ``gpu_lines``."""
    from ..fibers import fiber_count, ring_layout

    s: GroomSource = scene.source
    lo, hi = s.bbox
    lines = [
        f"{'groom file':<{_W}}{s.path} ({s.format})",
        f"{'strands':<{_W}}{s.strands:,} of {s.strands_in_file:,} in the file (skipped on load: "
        f"{_count(s.skipped)}; dropped for guides: {_count(s.dropped)})",
        f"{'vertices':<{_W}}{s.vertices:,} ({s.vertices / max(s.strands, 1):.1f} per strand)",
        f"{'up axis':<{_W}}file {s.up} -> +Z: {s.up_reason}",
        f"{'groom bbox':<{_W}}{np.round(lo, 4).tolist()} .. {np.round(hi, 4).tolist()} "
        f"(size {np.round(hi - lo, 4).tolist()}, scale {s.scale:g})",
    ]
    if s.cluster:
        lines.append(f"{'guides from':<{_W}}{s.guides:,} k-means clusters of strands (scene.groom_cluster = "
                     f"{s.cluster}): {s.strands - sum(s.dropped.values()):,} strands share them")
    else:
        why = "" if not s.cluster_requested else f", not fewer than the {s.guides:,} strands"
        lines.append(f"{'guides from':<{_W}}one per strand (scene.groom_cluster = {s.cluster_requested}{why})")
    if s.children:
        lines.append(f"{'children':<{_W}}{s.children} interpolated per guide (scene.groom_children): "
                     f"{s.guides:,} guides in all, each child the blend of its nearest strands' shapes, rooted "
                     f"between them")
    lines.append(f"{'segments':<{_W}}{s.segments} per guide, {scene.n_segments:,} containers; {s.segments_reason}")
    r = s.radii
    spread = f"{r[0]:.4g}" if np.all(r == r[0]) else f"median {np.median(r):.4g} (min {r.min():.4g}, max {r.max():.4g})"
    lines.append(f"{'container radius':<{_W}}{spread}: {s.radius_reason}")
    if s.native:
        fit = "the guides are the file's own vertices, so every strand runs on its container's axis"
    elif s.cluster:
        fit = (f"95% of guides stay within {s.chord_p95:.2f} radii of their cluster's mean strand; each "
               f"radius holds 90% of the cluster's strands")
    else:
        fit = f"95% of strands stay within {s.chord_p95:.2f} container radii of their guide's axis"
    lines.append(f"{'guide fit':<{_W}}{fit}; sharpest joint {s.max_turn:.0f} degrees")
    _, fibers = fiber_count(p, scene.n_guides)
    per_container = ring_layout(p).fibers_per_container
    lines.append(f"{'fibers rendered':<{_W}}{fibers:,} = {scene.n_guides:,} guides x {per_container:,} per "
                 f"container: {fibers / max(s.strands, 1):,.1f} fibers per file strand")
    from .grooms.groom import colour_summary
    lines.append(f"{'colours':<{_W}}{colour_summary(scene.guide_colors, p['look.color_source'])}")
    lines += gpu_lines
    if s.seconds:
        lines.append(f"{'build time':<{_W}}" + ", ".join(f"{k} {t:.3f} s" for k, t in s.seconds.items()))
    for w in s.warnings:
        lines.append(f"{'warning':<{_W}}{w}")
    return lines
