"""A groom's own strands, drawn as an artist's child-strand interpolation would: the reference the virtual
fibers are judged against (issue 15, "Judged against the groom's own strands").

What is drawn. Every strand of the file (the loader's Z-up strands, the same world frame as the virtual
scene), resampled to ``n_segments`` equal arc-length pieces -- the file's own resolution, up to
``MAX_SEGMENTS`` -- and around each one ``children`` child strands. A child is its parent offset by a
fixed random point of the parent's normal plane, uniform over a disc of radius R, carried along the strand
in the parent's parallel-transported frame (so a child follows every bend of its parent, as Blender's
"simple" children and XGen's clumped children do without clump or noise). R is the virtual scene's
container radius, which ``scene_from_groom`` ties to strand spacing (0.75 x the median distance between
neighbouring roots), so children of neighbouring strands just overlap, as an artist sets them. Children run
the full strand length; by default their offset stays R to the tip (``tip_taper`` gathers them there).

How it is drawn. The explicit baseline's ribbons and shading (``ExplicitRenderer.set_fibers``): each piece
of a parent strand is a container row like the virtual renderer's (``grooms.container_rows``: frames
transported minimally, joints closed by bisecting planes), each child one instance per row, clipped by the
joint planes, so children run on across joints without gaps. Same camera (``Camera.from_params`` of the
virtual scene), same light, same look parameters.

Count. As many children per strand as the virtual renderer draws fibers per strand with the same
parameters, unless strands x pieces x children would pass ``MAX_INSTANCES`` ribbons (6-12 s a frame on
this 2-core llvmpipe machine): then fewer children, each widened so that children x width -- the projected
cross-section of a strand's children -- stays the virtual one's (``Reference.capped`` says so). The
density self-shadow takes the virtual fiber density of ``p`` (``set_fibers`` keeps the look uniforms), which
that widening keeps equal to the children's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..params import Params
from ..render.camera import Camera
from ..render.explicit import ExplicitRenderer
from ..render.renderer import Frame
from ..scene.containers import Scene

MAX_INSTANCES = 8_000_000      # ribbons (strand pieces x children): 96 MB of instances, 6-12 s per frame here
MAX_SEGMENTS = 24              # pieces per strand: a strand keeps its own vertices up to this many
MAX_WIDENED_RADIUS = 0.25      # a widened child is at most this fraction of R: past it a child is a tube
SEED = 15


@dataclass
class Reference:
    """One groom's reference strands, ready for ``ExplicitRenderer.set_fibers``."""
    scene: Scene                   # rows: every piece of every file strand, radius R
    records: np.ndarray            # (rows * children, 6) uint16 instance records
    strands: int
    n_segments: int
    children: int                  # per strand
    fiber_radius: float            # child radius, fraction of R
    virtual_fibers: int            # what the virtual renderer draws for the same groom and parameters
    capped: bool                   # fewer children than virtual fibers per strand (MAX_INSTANCES)
    tip_taper: float = 0.0         # the children's offset at the tip is (1 - tip_taper) R

    @property
    def fibers(self) -> int:
        return self.strands * self.children

    @property
    def instances(self) -> int:
        return len(self.records)


def child_offsets(strands: int, children: int, seed: int = SEED) -> np.ndarray:
    """(strands, children, 2) points of the unit disc, uniform by area, the same for the same seed.

    Child 0 of every strand is the strand itself (offset 0), so the file's strands are always drawn."""
    if strands < 0 or children < 1:
        raise ValueError(f"child_offsets: need strands >= 0 and children >= 1, not {strands}, {children}")
    rng = np.random.default_rng(seed)
    r = np.sqrt(rng.random((strands, children)))
    a = rng.random((strands, children)) * 2.0 * np.pi
    out = np.stack([r * np.cos(a), r * np.sin(a)], -1)
    out[:, 0] = 0.0
    return out


def child_records(rows: np.ndarray, offsets: np.ndarray, seed: int = SEED) -> np.ndarray:
    """Instance records (rows * C, 6) for children at unit offsets ``offsets`` (S, C, 2) of their strand's
    pieces ``rows`` (the container rows of S strands, strand-major, column 19 the strand index): d in the
    piece's frame, [t0, t1] between the piece's two joint planes, random tint and roughness bytes.

    A child at unit offset c is P(z) = p0 + w(z) (cx ex + cy ey) + z ez in its piece's frame, w(z) = r0 +
    kappa z; it crosses the plane through A with normal n where n . (p0 - A) + w(z) (n . d) + z (n . ez) = 0."""
    rows = np.asarray(rows, np.float64)
    strand = rows[:, 19].astype(np.int64)
    c = offsets[strand]                                             # (R, C, 2)
    p0, p1 = rows[:, 0:3], rows[:, 4:7]
    axis = p1 - p0
    h = np.linalg.norm(axis, axis=1)
    ez = axis / h[:, None]
    ex = rows[:, 16:19] - ez * np.sum(rows[:, 16:19] * ez, 1, keepdims=True)
    ex /= np.linalg.norm(ex, axis=1, keepdims=True)
    ey = np.cross(ez, ex)
    d = c[..., 0:1] * ex[:, None] + c[..., 1:2] * ey[:, None]       # (R, C, 3), |d| <= 1
    r0 = rows[:, 3][:, None]
    kappa = ((rows[:, 7] - rows[:, 3]) / h)[:, None]            # a tapered piece: w(z) = r0 + kappa z
    n0, n1 = rows[:, 8:11], rows[:, 12:15]
    q0, q1 = np.einsum("rcx,rx->rc", d, n0), np.einsum("rcx,rx->rc", d, n1)
    with np.errstate(divide="ignore", invalid="ignore"):
        z0 = -r0 * q0 / (kappa * q0 + np.sum(n0 * ez, 1)[:, None])
        z1 = (h[:, None] * np.sum(n1 * ez, 1)[:, None] - r0 * q1) / (kappa * q1 + np.sum(n1 * ez, 1)[:, None])
    t0 = np.where(np.isfinite(z0), z0 / h[:, None], 0.0)
    t1 = np.where(np.isfinite(z1), z1 / h[:, None], 1.0)
    t1 = np.maximum(t0, t1)
    half = np.empty(c.shape[:2] + (5,), np.float16)
    half[..., 0:3] = d
    half[..., 3] = t0
    half[..., 4] = t1
    out = np.empty(c.shape[:2] + (6,), np.uint16)
    out[..., :5] = half.view(np.uint16)
    rng = np.random.default_rng(seed + 1)
    look = rng.integers(0, 256, (offsets.shape[0], offsets.shape[1], 2)).astype(np.uint16)[strand]
    out[..., 5] = look[..., 0] | (look[..., 1] << np.uint16(8))
    return out.reshape(-1, 6)


def build(p: Params, virtual_scene: Scene, *, max_instances: int = MAX_INSTANCES, seed: int = SEED,
          tip_taper: float = 0.0) -> Reference:
    """The reference strands of the groom ``p["scene.groom_file"]`` beside its virtual scene under ``p``
    (whose container radius and origin it takes, and whose fiber count it matches, see the module).

    ``tip_taper`` (0 .. 1): the children's offset shrinks linearly along the strand to (1 - tip_taper) of
    R at the tip, so children gather toward their strand's tip (Blender's Clump); 0, the default, keeps
    the offset constant."""
    if not 0.0 <= tip_taper <= 1.0:
        raise ValueError(f"strand reference: tip_taper = {tip_taper:g}; it must be in 0 .. 1")
    from ..fibers import ring_layout
    from ..scene.grooms import container_rows, load_groom, resample_many

    if p["scene.generator"] != "groom":
        raise ValueError(f"strand reference: scene.generator is {p['scene.generator']!r}; it needs a groom file")
    groom = load_groom(p["scene.groom_file"], up=p["scene.groom_up"], scale=p["scene.groom_scale"])
    lengths = groom.lengths()
    lo, hi = groom.bbox()
    keep = np.flatnonzero(lengths > 1e-9 * max(float(np.linalg.norm(hi - lo)), 1e-30))
    if len(keep) == 0:
        raise ValueError(f"{groom.path.name}: no strand with a length to draw")
    counts = np.array([len(groom.strands[i]) for i in keep])
    n_seg = int(np.clip(np.median(counts) - 1, 1, MAX_SEGMENTS))
    polylines = resample_many([groom.strands[i] for i in keep], n_seg)
    ok = (np.linalg.norm(np.diff(polylines, axis=1), axis=2) > 0).all(axis=1)
    polylines = polylines[ok]                       # a strand folded onto itself at n_seg pieces: left out
    S = len(polylines)
    R = float(np.median(virtual_scene.segments[:, 3]))
    rows = container_rows(polylines, np.full(S, R), tip_taper, virtual_scene.origin).astype(np.float32)
    F = ring_layout(p).fibers_per_container
    virtual_fibers = F * virtual_scene.n_guides
    per_strand = max(1, round(virtual_fibers / S))
    children = int(min(per_strand, max(1, max_instances // max(1, len(rows)))))
    fiber_radius = float(p["fibers.fiber_radius"])
    if children < per_strand:
        fiber_radius = min(MAX_WIDENED_RADIUS, fiber_radius * per_strand / children)
    records = child_records(rows, child_offsets(S, children, seed), seed)
    scene = Scene(rows, virtual_scene.origin, f"{groom.path.stem} strands", S)
    return Reference(scene, records, S, n_seg, children, fiber_radius, virtual_fibers, children < per_strand,
                     tip_taper)


def render(ctx, ref: Reference, p: Params, cam: Camera, size: tuple[int, int],
           explicit: ExplicitRenderer | None = None) -> Frame:
    """The reference frame (colour and ids) through the explicit baseline's ribbons."""
    e = explicit or ExplicitRenderer(ctx)
    e.set_fibers(ref.scene, ref.records, ref.children, ref.fiber_radius)
    try:
        return e.render(p, cam, size, outputs=("color", "ids"))
    finally:
        if explicit is None:
            e.release()
            e.release_targets()
