"""A scene built from a groom file, and what ``vfiber info`` says about it.

``GroomScene`` is a :class:`~app.scene.containers.Scene` (containers only, nothing per fiber) that also
remembers the facts of its source: how many strands and vertices the file held, what was skipped or dropped
and why, which axis was taken as up and why, how the guides were made. ``source_info()`` turns those facts
and the parameters the scene was built with into the lines ``vfiber info`` prints after its own.

The byte comparison needs the renderers' sizes, so this one module reaches from the scene into
``app.render`` -- lazily, inside :func:`gpu_bytes`, for reporting only; nothing on the path from parameters to
image goes through here.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..params import Params
from ..units import human_bytes
from .containers import Scene

POLYLINE_VERTEX_BYTES = 12
"""One float32 xyz vertex: the plainest explicit store, every fiber a polyline through its guide's joints."""

_W = 17  # label column width, as in ``app.cli.cmd_info``


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
    seconds: dict[str, float] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)


@dataclass(eq=False)
class GroomScene(Scene):
    """Containers made from a groom file, plus where they came from."""

    source: GroomSource | None = None
    params: Params | None = None

    def source_info(self, p: Params | None = None) -> list[str]:
        """Lines for ``vfiber info``; fiber counts and bytes follow ``p`` (default: the build parameters),
        so a viewer that changes ``fibers.*`` without rebuilding the scene can pass its current ones."""
        return source_info(self, p or self.params or Params({}))


def gpu_bytes(scene: Scene, p: Params) -> dict[str, tuple[int, str]]:
    """GPU bytes of the virtual scene and of explicit stores of the same fibers, each with its formula.

    ``virtual``: what ``Renderer.set_scene`` allocates (container segments plus the proxy rectangle).
    ``explicit``: ``app.render.explicit.estimate_bytes`` -- the explicit baseline's own allocation for
    exactly these fibers -- when that module is importable. ``polylines``: every fiber as a float32 xyz
    polyline through its guide's joints, the plainest explicit store (no tangents, widths or colours, so a
    real one is larger still).
    """
    from ..fibers import fiber_count

    try:
        from ..render.renderer import scene_gpu_bytes
        virtual = (scene_gpu_bytes(scene), "container segments + their hierarchy + proxy rectangle (Renderer.set_scene)")
    except ImportError:
        virtual = (scene.nbytes, "container segments")
    _, fibers = fiber_count(p, scene.n_guides)
    joints = scene.n_segments // max(scene.n_guides, 1) + 1     # vertices per fiber polyline
    out = {"virtual": virtual,
           "polylines": (fibers * joints * POLYLINE_VERTEX_BYTES,
                         f"{fibers:,} fibers x {joints} vertices x {POLYLINE_VERTEX_BYTES} B (float32 xyz)")}
    try:
        from ..render import explicit
        pl = explicit.plan(scene, p)
        out["explicit"] = (int(explicit.estimate_bytes(scene, p)),
                           f"ExplicitRenderer: {explicit.INSTANCE_BYTES} B per fiber per segment "
                           f"({pl.instances:,}) + {explicit.ROW_BYTES} B per segment")
    except (ImportError, AttributeError):   # the explicit baseline is optional here
        pass
    return out


def _count(d: dict[str, int]) -> str:
    return ", ".join(f"{n:,} {why}" for why, n in d.items()) if d else "none"


def source_info(scene: Scene, p: Params) -> list[str]:
    """Lines for ``vfiber info``: the file, what was kept, orientation, guides, fibers and bytes."""
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
    sizes = gpu_bytes(scene, p)
    v = sizes["virtual"][0]
    lines.append(f"{'GPU virtual':<{_W}}{v:,} B ({human_bytes(v)}): {sizes['virtual'][1]}")
    for key, label in (("explicit", "GPU explicit"), ("polylines", "GPU polylines")):
        if key in sizes:
            b, how = sizes[key]
            lines.append(f"{label:<{_W}}{b:,} B ({human_bytes(b)}), {b / max(v, 1):,.0f}x virtual: {how}")
    if s.seconds:
        lines.append(f"{'build time':<{_W}}" + ", ".join(f"{k} {t:.3f} s" for k, t in s.seconds.items()))
    for w in s.warnings:
        lines.append(f"{'warning':<{_W}}{w}")
    return lines
