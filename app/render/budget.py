"""How much work a frame is, from the parameters, the scene and the image size, before anything renders.

Every input is bounded, but their products are not: 64 rings of 0.01-degree curled, twisted fibers render a
64 x 64 image for minutes; 200,000 guides of 64 segments, 4 x 4 supersampling with traced shadows, 5,000
clusters of a 200k-strand groom likewise. A person should learn that before waiting, so the command line
(``vfiber render``) and the viewer call :func:`estimate` first and show :meth:`WorkEstimate.summary`;
above :data:`SLOW_SECONDS` the command line stops and says how to go on (``--allow-slow``).

The model (deliberately simple, held against the renderer's own ``cost`` output, the fiber tests it
counted per pixel, by ``tests/test_hostile.py::test_estimate_follows_the_renderers_own_cost``):

* **containers**: the scene's segments; **fragments**: the pixels their proxies cover, from each segment's
  projected length and width at its depth (the camera the renderer would use), times ``render_scale``^2.
  A frame the renderer walks (``renderer.choose_visibility``: dense grooms, the filtered mode) traverses
  only the containers in front of each covered pixel's fiber instead, ``WALK_ENTERED`` a pixel, and pays
  the walk's steps through the hierarchy, ``WALK_STEPS_PER_LEVEL`` a level;
* **rays** per fragment: ``supersample``^2 or the MSAA samples (brute mode casts one), twice with traced
  shadows;
* **fiber tests** per ray: brute force tests every fiber of the container; fast and exact test, on the
  rings a ray crosses (half of them on average, on a front and a back piece), the fibers of each ring's
  candidate window: what the piece sweeps seen from the axis plus each fiber's reach, plus the curl
  disc and the twist over the segment for curved fibers. A curved test costs ``MAX_SUB + 2`` loop passes.
* **draws**: the renderer's own ``draw_ranges`` (how often every container is drawn), when it offers it.
* **the filter** (``quality.filter = coverage``, exact mode: ``renderer.filtered``; the default): the
  model counts the walk's traversal, not the footprint's scan and compositing; a filtered frame's seconds
  are its walk's times ``FILTERED_COST``, the filtered frame's measured time over the unfiltered walk's.
* **seconds**: work over a throughput measured on llvmpipe (2 cores, Mesa 22.3.6): an order of magnitude,
  not a promise; on a GPU it is far faster.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..fibers import MAX_SUB, Shape, ring_layout
from ..params import Params

SLOW_SECONDS = 60.0          # above this the command line asks for --allow-slow
CURVED_TEST_PASSES = 1 + MAX_SUB + 1   # a curved-fiber test walks its chord pieces
# Fitted on llvmpipe, 2 cores, Mesa 22.3.6, to timed 320x180 renders of 11 looks (default, brute, fast,
# 64 rings, curl, twist, ellipsoid, 3x3 supersampling, traced shadows, 2,000 guides, 16 bent segments):
# loop passes per second in the traversal, and the fixed cost of a covered fragment (proxy, shading).
PASSES_PER_SECOND = 4.0e7
TYPICAL_SWEEP = 0.3          # a typical piece of a ray sweeps this fraction of acos(inner / outer)
TYPICAL_TWIST = 0.1          # ... and this fraction of its segment's twist
FRAGMENTS_PER_SECOND = 1.0e6
# The walk (quality.visibility, renderer.py), per covered pixel, from the grooms bench (docs/bench/grooms,
# 640x360 exact): containers traversed 1.4-2.1 on the five shared grooms; walk steps 1.6-3.8 per level of
# the hierarchy (harolongo 65 over 17.3 levels, sintel 23 over 10.4, Table 4's 200 containers 12.5 over 7.6).
WALK_ENTERED = 2.0
WALK_STEPS_PER_LEVEL = 3.0
# A filtered frame is estimated as the walk it takes (choose_visibility), times this: its process_time over the
# unfiltered frame's drawn by the same walk, on llvmpipe here: default preset 2.0x at 800x450 (1.4x at 320x180,
# docs/antialias.md: 46 ms against 62-65), the default preset with shape.ellipsoid = 1 1.4x (800x450), sintel
# 2.9x (320x180; its unfiltered frame walks too), harolongo 4.6x (one run). 2.0, the default preset's: the
# dense grooms' filtered frames take more than this says (their walks' steps dominate their estimates).
FILTERED_COST = 2.0


# Scene.from_polylines builds containers one segment at a time: about 0.2 ms each here (5,000 guides of 64
# segments took 63 s), so 200,000 guides of 64 segments would take ~40 minutes before the first pixel.
SECONDS_PER_GENERATED_SEGMENT = 2.0e-4
# k-means (app/scene/grooms/guides.py: _kmeans) on this machine: 60-370 ns per strand x cluster, measured at
# 8,000-50,000 strands and 500-5,000 clusters; the upper end, so a slow clustering is never waved through
SECONDS_PER_STRAND_CLUSTER = 4.0e-7
# Bytes per output pixel a frame holds at its peak: the render targets (colour 4, ids 16, normal+depth 16,
# depth buffer 4) on llvmpipe's system-memory framebuffers, their read-backs and the composited image;
# measured: 9000 x 9000 peaked at 8 GB, 81 M pixels.
BYTES_PER_PIXEL = 100
MAX_FRAME_BYTES = 4 * 1024**3  # above this a frame needs --allow-slow (and that much free memory)


def build_seconds(p: Params) -> float:
    """Seconds to build the scene, before building it: a generated scene by its segments; a groom by the
    k-means that scene.groom_cluster asks for (reading the file is fast; clustering 200,000 strands into
    5,000 guides is minutes)."""
    if p["scene.generator"] == "groom":
        return cluster_seconds(p)
    segments = p["scene.count"] * p["scene.segments"] if p["scene.generator"] != "single" else p["scene.segments"]
    return segments * SECONDS_PER_GENERATED_SEGMENT


def cluster_seconds(p: Params) -> float:
    """Seconds scene.groom_cluster's k-means takes on this groom: strands x clusters x
    SECONDS_PER_STRAND_CLUSTER (0 without clustering, or with at least as many clusters as strands)."""
    k = p["scene.groom_cluster"]
    if k <= 0 or not p["scene.groom_file"]:
        return 0.0
    from ..scene.grooms import load_groom

    n = load_groom(p["scene.groom_file"], p["scene.groom_up"], p["scene.groom_scale"]).n_strands
    return 0.0 if k >= n else n * k * SECONDS_PER_STRAND_CLUSTER


def frame_bytes(size: tuple[int, int]) -> int:
    """Peak memory of one frame at ``size`` (width, height), render targets and read-backs."""
    return int(size[0]) * int(size[1]) * BYTES_PER_PIXEL


@dataclass(frozen=True)
class WorkEstimate:
    pixels: int              # the image, after render_scale
    containers: int          # container segments drawn per pass
    fragments: float         # container fragments (pixels times how many proxies cover each)
    rays: int                # traversals per fragment
    tests_per_ray: float     # fiber tests one traversal makes, on average
    passes_per_test: int     # loop passes one fiber test costs
    draws: int | None        # times every container is drawn per pass (None: unknown)
    mode: str
    visibility: str = "proxies"     # how the renderer finds each pixel's containers (renderer.choose_visibility)
    walk_steps: float = 0.0         # steps through the hierarchy per ray over the frame (walked frames)
    filtered: bool = False          # quality.filter = coverage in exact mode: seconds times FILTERED_COST

    @property
    def fiber_tests(self) -> float:
        return self.fragments * self.rays * self.tests_per_ray

    @property
    def seconds(self) -> float:
        passes = (self.fiber_tests * self.passes_per_test + self.walk_steps * self.rays)
        frag_work = self.fragments * self.rays * (self.draws or 1)
        return (passes / PASSES_PER_SECOND + frag_work / FRAGMENTS_PER_SECOND) * (FILTERED_COST if self.filtered
                                                                                 else 1.0)

    @property
    def slow(self) -> bool:
        return self.seconds > SLOW_SECONDS

    def summary(self) -> str:
        """One line: what the frame costs and about how long it takes here."""
        draws = f", {self.draws} draws" if self.draws and self.draws > 1 else ""
        found = "containers walked into" if self.visibility == "walk" else "container fragments"
        mode = f"{self.mode} mode, filtered" if self.filtered else f"{self.mode} mode"
        return (f"about {_count(self.fiber_tests)} fiber tests ({mode}: {_count(self.fragments)} "
                f"{found} of {self.containers:,} containers on {self.pixels:,} pixels, "
                f"{self.rays} ray{'s' if self.rays > 1 else ''} each, {_count(self.tests_per_ray)} tests per "
                f"ray{draws}): roughly {_duration(self.seconds)} on llvmpipe")


def estimate(p: Params, scene, size: tuple[int, int], mode: str | None = None) -> WorkEstimate:
    """The work of rendering ``scene`` with ``p`` at ``size`` (width, height), before rendering it."""
    mode = mode or p["quality.mode"]
    scale = p["quality.render_scale"]
    width, height = max(1, round(size[0] * scale)), max(1, round(size[1] * scale))
    fragments, visibility, steps = _containers_met(p, scene, (width, height), mode)
    rays = 1 if mode == "brute" else max(p["quality.supersample"] ** 2, p["quality.msaa"], 1)
    rays *= 2 if p["look.self_shadow"] == "traced" else 1
    tests, passes = _tests_per_ray(p, scene, mode)
    from .renderer import filtered

    return WorkEstimate(width * height, int(scene.n_segments), fragments, rays, tests, passes,
                        _draws(p, scene, mode, rays), mode, visibility, steps, filtered(p, mode))


def _containers_met(p: Params, scene, size: tuple[int, int], mode: str) -> tuple[float, str, float]:
    """(containers traversed over the frame, the renderer's visibility, walk steps over the frame). Drawn
    as proxies, every proxy fragment traverses its container; walked, a covered pixel traverses about
    WALK_ENTERED containers, covered pixels being the proxies' fragments over the layers they stack."""
    from .camera import Camera
    from .renderer import choose_visibility, proxy_layers

    if scene.n_segments == 0:
        return 0.0, "proxies", 0.0
    cam = Camera.from_params(p, scene, aspect=size[0] / size[1])
    fragments = _fragments(scene, cam, size)
    auto = p["quality.visibility"] == "auto"
    layers = proxy_layers(scene, cam, size) if auto else math.nan
    visibility = choose_visibility(p, mode, layers)
    if visibility == "proxies":
        return fragments, visibility, 0.0
    if not auto:
        layers = proxy_layers(scene, cam, size)
    covered = min(float(size[0] * size[1]), fragments / max(layers, 1.0)) if math.isfinite(layers) \
        else float(size[0] * size[1])
    levels = max(1.0, math.log2(scene.n_segments))
    return (min(fragments, covered * WALK_ENTERED), visibility, covered * WALK_STEPS_PER_LEVEL * levels)


def _fragments(scene, cam, size: tuple[int, int]) -> float:
    """Pixels covered by container proxies, counted once per proxy: each segment's projected length plus
    its diameter, times its diameter, at the depth of its middle; no more than the image per proxy."""
    width, height = size
    seg = scene.segments.astype(np.float64)
    a, b = seg[:, 0:3] + scene.origin, seg[:, 4:7] + scene.origin
    radius = np.maximum(seg[:, 3], seg[:, 7])
    depth = np.linalg.norm(0.5 * (a + b) - np.asarray(cam.position, np.float64), axis=1)
    depth = np.maximum(depth - radius, max(cam.near, 1e-9))
    focal = height / (2.0 * math.tan(math.radians(cam.fov) / 2.0))
    length_px = np.linalg.norm(b - a, axis=1) * focal / depth
    width_px = 2.0 * radius * focal / depth + 1.0          # a proxy is at least a pixel wide
    area = np.minimum((length_px + width_px) * width_px, float(width * height))
    return float(area.sum())


def _tests_per_ray(p: Params, scene, mode: str) -> tuple[float, int]:
    lay = ring_layout(p)
    shaped = Shape.from_params(p).curved
    # the curl's, frizz's and noise's reach together, in unit space as the traversal takes it (shape.py:
    # Shape.displacement; the parameters are ring widths, which this once used as unit space, ten times
    # the reach on ten rings)
    moved = Shape.from_params(p).displacement
    passes = CURVED_TEST_PASSES if shaped else 1
    if mode == "brute":
        return float(lay.fibers_per_container) * (2 if shaped else 1), passes
    k = lay.rings
    outer = 1.0 - np.arange(k) / k
    inner = outer - 1.0 / k
    rho = np.maximum(lay.rho, 1e-6)
    # a piece of a typical ray through ring i's annulus sweeps a fraction of the most it can, seen from
    # the axis; the candidate window adds each fiber's reach on both sides
    sweep = TYPICAL_SWEEP * np.arccos(np.clip(inner / outer, 0.0, 1.0))
    # (the ellipsoid no longer widens this: the shaped traversal cuts each arc to the heights it spans and
    # scales the band to them, glsl/fibers/shaped.glsl)
    window = sweep + 2.0 * lay.reach
    reach = np.full(k, lay.fiber_radius)
    if shaped:
        curl = moved + lay.fiber_radius
        disc = np.where(rho > curl, np.arcsin(np.minimum(1.0, curl / rho)), math.pi)
        window = window + 2.0 * disc
        reach = reach + moved
        if p["shape.twist"]:
            per_segment = 1.0 / max(1, _segments_per_guide(scene))
            # a piece spans a short stretch of the axis: it sees a small part of the segment's twist
            window = window + TYPICAL_TWIST * 2.0 * math.pi * abs(p["shape.twist"]) * per_segment
    candidates = np.minimum(lay.n, np.floor(window / lay.dphi) + 1)
    # Exact and fast stop once a ring's front piece hits: the chance of that is about the fraction of the
    # ring's circumference its fibers shade (each fiber 2 x radius wide, curls wider).
    hit = np.clip(lay.n * 2.0 * reach / (2.0 * math.pi * rho), 0.0, 1.0) if lay.fiber_radius > 0 else 0.0 * rho
    reached = np.concatenate([[1.0], np.cumprod(1.0 - hit)[:-1]])
    visited = 1.0 - np.arange(k) / k          # a ray at a uniform offset from the axis crosses ring i this often
    pieces = 2 if shaped else 1               # on the way in; curved fibers sit on two arcs
    misses = float((reached * (1.0 - hit)).prod()) if k else 1.0
    tests = float((pieces * visited * reached * candidates).sum())
    tests += misses * float((pieces * visited * candidates).sum())   # a miss walks the back pieces too
    if mode == "fast":
        tests *= 0.7                          # first hit wins, not the nearest
    return max(tests, 1.0), passes


def _segments_per_guide(scene) -> int:
    guides = getattr(scene, "n_guides", 0) or 0
    return max(1, round(scene.n_segments / guides)) if guides else 1


def _draws(p: Params, scene, mode: str, rays: int) -> int | None:
    try:  # the renderer's own packing of fibers into draws; it may change, so this is best effort
        from .renderer import draw_ranges
        return len(draw_ranges(p, scene, mode, rays))
    except Exception:  # noqa: BLE001 - an estimate never stops a render
        return None


def _count(x: float) -> str:
    for unit, size in (("T", 1e12), ("G", 1e9), ("M", 1e6), ("k", 1e3)):
        if x >= size:
            return f"{x / size:.1f}{unit}"
    return f"{x:.0f}"


def _duration(seconds: float) -> str:
    if seconds < 1:
        return "under a second"
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.0f} h"
