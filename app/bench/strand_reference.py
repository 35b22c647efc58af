"""A groom's own strands, drawn as an artist's child-strand interpolation would: the reference the virtual
fibers are judged against (issue 15, "Judged against the groom's own strands").

Two ways to add children to the file's strands (the loader's Z-up strands, the same world frame as the
virtual scene, resampled to ``n_segments`` equal arc-length pieces -- the file's own resolution, up to
``MAX_SEGMENTS``); ``build(..., method=...)`` picks one.

``"interpolated"`` (the default): what Blender's "Interpolate Hair Curves" node or XGen's guide
interpolation make. The file's strands are the guides, and each is drawn itself. Child roots are spread
between the guide roots: there is no scalp mesh, so each child takes a guide root (the guides in turn, so
every guide gets the same number, as vfiber's containers get the same fibers each) plus a random offset,
uniform by area, over a disc in the plane normal to that guide's first piece whose radius is the local
root spacing (that root's distance to its nearest neighbour, clipped to 0.5 .. 2 x the median). That choice
is robust where a triangulation of the roots would not be: it needs no surface, keeps a lone strand's
children next to it instead of bridging to a far neighbour, and is the same recipe for 100 strands
(Bangs, Curly), 7,905 (harolongo) and Ratboy's 9 stubs shorter than 1e-3. Each child's shape is the
weighted blend of the root-relative shapes of its ``K_GUIDES`` nearest guides (by root distance), all
resampled to the same arc-length parameter first: weight (1 - (d / h)^2)^2 / d^2, inverse distance squared
with a smooth falloff that reaches 0 at h, the distance of the next guide out, so a guide's influence fades
in and out continuously as children move between neighbourhoods. A child whose root is a guide's root is
that guide. Then a mild clump pulls the child toward its nearest guide, ``clump`` s^2 of the way at arc
fraction s, and its length is a random 1 - ``length_variation`` .. 1 of the blend's. Children taper in width
from R f at the root to ``tip_width`` of that at the tip (the ribbon's width is the row radius times
``uFiberRadius``: glsl/explicit/ribbon.vert), so ends are points.

``"disc"``: the earlier reference, kept so the docs can show both. Around each strand ``children`` child
strands, each its parent offset by a fixed random point of the parent's normal plane, uniform over a disc of
radius R, carried along the strand in the parent's parallel-transported frame (Blender's "simple" children
without clump or noise). Full length, constant width; ``tip_taper`` gathers the offsets toward the tip.

R is the virtual scene's container radius, which ``scene_from_groom`` ties to strand spacing (0.75 x the
median distance between neighbouring roots).

How it is drawn. The explicit baseline's ribbons and shading (``ExplicitRenderer.set_fibers``). Disc
children: each piece of a parent strand is a container row like the virtual renderer's
(``container_rows``: frames transported minimally, joints closed by bisecting planes), each child one
instance per row, clipped by the joint planes. Interpolated children have a shape of their own, so each is
its own chain of rows with radius R (tapering), one instance per row. The ribbon shader reads a fiber's
depth in its container, |d|, for sky occlusion and the density self-shadow (the light's path to the
container's wall). An interpolated child has no container, so those terms mean nothing for it: drawn at
random depths (the disc's distribution), each as if at that depth in a container of its own whatever side
of the hair it is on, the visible children were shadowed like buried ones (sintel's reference fell from
luma 0.60 to 0.25), where the disc reference's visible children sit on the lit side of
their disc and are barely shadowed (0.604 with self-shadow, 0.610 without). So every interpolated child is
drawn at depth 1, on the wall: no self-shadow, no occlusion, the look of ``look.self_shadow=off``. The
depth is stored as d = depth x the row's own axis: P(t) = p0 + t (p1 - p0) + w(t) d then stays on the
row's axis, and [t0, t1] is solved so that the ribbon runs exactly from joint to joint.

``"strands"``: the file's strands alone, no child, each as one fiber ``MAX_WIDENED_RADIUS`` R wide at full
width. Not a picture of the hair: too thin for coverage, it is the check the other two (and every vfiber
variant) are held to, that a picture's hair runs where the groom's own strands run (``looks``: "deg vs
strands"). It is what showed that on Curly_100 the interpolated reference's shading bands run across the
strands (about 50 degrees off them), not along them.

Same camera (``Camera.from_params`` of the virtual scene), same light, same look parameters.

Count. As many fibers as the virtual renderer draws with the same parameters, unless fibers x pieces would
pass ``MAX_INSTANCES`` ribbons (6-12 s a frame on this 2-core llvmpipe machine): then fewer, each widened so
that fibers x width -- the projected cross-section of the hair -- stays the virtual one's
(``Reference.capped`` says so). The density self-shadow takes the virtual fiber density of ``p``
(``set_fibers`` keeps the look uniforms), which that widening keeps equal to the children's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..params import Params
from ..render.camera import Camera
from ..render.explicit import ExplicitRenderer
from ..render.renderer import Frame
from ..scene.containers import Scene
from ..scene.grooms.guides import nearest_points, root_spacing

MAX_INSTANCES = 8_000_000      # ribbons (strand pieces x children): 96 MB of instances, 6-12 s per frame here
MAX_SEGMENTS = 24              # pieces per strand: a strand keeps its own vertices up to this many
MAX_WIDENED_RADIUS = 0.25      # a widened child is at most this fraction of R: past it a child is a tube
SEED = 15
METHODS = ("interpolated", "disc", "strands")
K_GUIDES = 4                   # guides blended per interpolated child
NEIGHBOUR_CANDIDATES = 16      # a child's blended guides are sought among its root guide's nearest this many
CLUMP = 0.25                   # interpolated children: pulled this far toward the nearest guide at the tip
LENGTH_VARIATION = 0.15        # interpolated children: length 1 - this .. 1 of the blend's
TIP_WIDTH = 0.2                # interpolated children: width at the tip, fraction of the root's
GUIDE_SAMPLES = 64             # pieces of the common arc-length parameter guides are blended on (at least)
_CHUNK = 32_768                # children per numpy pass: bounds the (chunk, points, guides, 3) temporaries


@dataclass
class Reference:
    """One groom's reference strands, ready for ``ExplicitRenderer.set_fibers``."""
    scene: Scene                   # rows: disc, every piece of every file strand, radius R; interpolated,
                                   # every piece of every child (the guides first)
    records: np.ndarray            # (rows * fibers_per_row, 6) uint16 instance records
    strands: int                   # file strands drawn (the guides)
    n_segments: int
    fibers: int                    # every fiber drawn, the file's strands included
    fibers_per_row: int            # disc: children per strand; interpolated: 1
    fiber_radius: float            # child radius, fraction of R
    virtual_fibers: int            # what the virtual renderer draws for the same groom and parameters
    capped: bool                   # fewer fibers than the virtual ones (MAX_INSTANCES)
    method: str = "interpolated"
    tip_taper: float = 0.0         # disc: the children's offset at the tip is (1 - tip_taper) R
    clump: float = 0.0             # interpolated: the settings it was made with
    length_variation: float = 0.0
    tip_width: float = 1.0
    dropped: int = 0               # interpolated children left out: a piece of zero length

    @property
    def children(self) -> float:
        """Fibers per file strand (the strand itself included)."""
        return self.fibers / max(1, self.strands)

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


# --------------------------------------------------------------------------------------------------
# Interpolated children (numpy, float64)
# --------------------------------------------------------------------------------------------------
def resample_guides(strands, n_segments: int) -> np.ndarray:
    """Every strand at ``n_segments`` equal arc-length pieces, (S, n_segments + 1, 3): the common parameter
    that shapes are blended on. A strand of zero length (or of one point) becomes its root repeated, which
    blends as no shape at all rather than as NaN."""
    from ..scene.grooms import resample_many

    if n_segments < 1:
        raise ValueError(f"resample_guides: n_segments must be >= 1, not {n_segments}")
    arrays = [np.asarray(s, np.float64).reshape(-1, 3) for s in strands]
    if any(len(a) == 0 for a in arrays):
        raise ValueError("resample_guides: a strand with no point has no root to grow from")
    out = np.repeat(np.stack([a[0] for a in arrays])[:, None] if arrays else np.zeros((0, 1, 3)),
                    n_segments + 1, axis=1)
    length = np.array([np.linalg.norm(np.diff(a, axis=0), axis=1).sum() if len(a) > 1 else 0.0 for a in arrays])
    scale = max(1e-300, float(np.max(np.abs(np.concatenate(arrays))))) if arrays else 1.0
    real = np.flatnonzero(length > 1e-12 * scale)
    if len(real):
        out[real] = resample_many([arrays[i] for i in real], n_segments)
    return out


def _first_directions(guides: np.ndarray) -> np.ndarray:
    """Unit direction each guide leaves its root in: its first piece, else root to tip, else +Z."""
    d = guides[:, 1] - guides[:, 0]
    n = np.linalg.norm(d, axis=1)
    chord = guides[:, -1] - guides[:, 0]
    nc = np.linalg.norm(chord, axis=1)
    d = np.where((n > 0)[:, None], d, np.where((nc > 0)[:, None], chord, [0.0, 0.0, 1.0]))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def child_roots(guides: np.ndarray, count: int, seed: int = SEED) -> tuple[np.ndarray, np.ndarray]:
    """``count`` child roots (count, 3) and the guide each was grown from (count,): the guides' own roots
    first (child i < S is guide i), then the guides in turn, each root offset uniformly by area over a disc
    of radius ``root_spacing`` in the plane normal to its guide's first piece. The same for the same seed."""
    from ..scene.containers import orthonormal_x

    S = len(guides)
    if S == 0 or count < S:
        raise ValueError(f"child_roots: {count} children for {S} guides; every guide is drawn itself")
    roots = guides[:, 0]
    parent = np.concatenate([np.arange(S), np.arange(count - S) % S])
    z = _first_directions(guides)
    ex = orthonormal_x(z)
    ey = np.cross(z, ex)
    rng = np.random.default_rng(seed)
    r = np.sqrt(rng.random(count - S)) * root_spacing(roots)[parent[S:]]
    a = rng.random(count - S) * 2.0 * np.pi
    p = parent[S:]
    out = roots[parent].copy()
    out[S:] += (r * np.cos(a))[:, None] * ex[p] + (r * np.sin(a))[:, None] * ey[p]
    return out, parent


def _shape_at(shapes: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Root-relative shapes (G, M, 3) at arc fractions s (N, P) of guides g: linear in the common parameter.
    ``shapes`` is indexed per child already: (N, k, M, 3) in, (N, k, P, 3) out."""
    M = shapes.shape[-2]
    x = np.clip(s, 0.0, 1.0) * (M - 1)
    i0 = np.minimum(np.floor(x).astype(np.int64), M - 2)
    f = (x - i0)[:, None, :, None]
    take = lambda i: np.take_along_axis(shapes, i[:, None, :, None], axis=2)
    return take(i0) * (1.0 - f) + take(i0 + 1) * f


def interpolate(guides: np.ndarray, roots: np.ndarray, n_segments: int, *, parents: np.ndarray | None = None,
                k: int = K_GUIDES, clump: float = CLUMP, lengths: np.ndarray | None = None) -> np.ndarray:
    """Child polylines (N, n_segments + 1, 3) growing from ``roots`` (N, 3) among ``guides`` (S, M, 3),
    guides already on a common arc-length parameter (``resample_guides``); see the module for the blend,
    the clump and the lengths (fractions of the blend's, default 1).

    ``parents`` (the guide each root was grown from, as ``child_roots`` gives) narrows the search for a
    child's nearest guides to that guide's ``NEIGHBOUR_CANDIDATES`` nearest; without it every guide is
    searched (fine for tests and small grooms)."""
    guides = np.asarray(guides, np.float64)
    roots = np.asarray(roots, np.float64).reshape(-1, 3)
    S, M = guides.shape[:2]
    N = len(roots)
    if S == 0 or M < 2:
        raise ValueError(f"interpolate: need guides of at least 2 points, not shape {guides.shape}")
    if not 0.0 <= clump <= 1.0:
        raise ValueError(f"interpolate: clump = {clump:g}; it must be in 0 .. 1")
    lengths = np.ones(N) if lengths is None else np.clip(np.asarray(lengths, np.float64), 0.0, 1.0)
    g_roots = guides[:, 0]
    shapes = guides - g_roots[:, None]
    scale = max(float(np.ptp(np.concatenate([g_roots, roots]), axis=0).max()), 1e-300)
    tiny = 1e-9 * scale
    kk = min(k, S)
    s = np.linspace(0.0, 1.0, n_segments + 1)
    out = np.empty((N, n_segments + 1, 3))
    if parents is not None:
        cand, _ = nearest_points(g_roots, g_roots, min(S, NEIGHBOUR_CANDIDATES))
    for a in range(0, N, _CHUNK):
        q = roots[a:a + _CHUNK]
        if parents is None:
            idx, dist = nearest_points(g_roots, q, kk + 1)
        else:
            c = cand[np.asarray(parents[a:a + _CHUNK], np.int64)]                  # (n, C)
            d = np.linalg.norm(g_roots[c] - q[:, None], axis=2)
            order = np.argsort(d, axis=1, kind="stable")[:, :kk + 1]
            idx, dist = np.take_along_axis(c, order, 1), np.take_along_axis(d, order, 1)
        # h: the next guide out; with no next guide (S <= k), twice the farthest, so all keep some weight
        h = dist[:, kk] if idx.shape[1] > kk else 2.0 * dist[:, -1] + tiny
        idx, dist = idx[:, :kk], dist[:, :kk]
        h = np.maximum(h, dist[:, -1] + tiny)[:, None]
        fall = (1.0 - (dist / h) ** 2) ** 2
        w = (fall + 1e-12) / np.maximum(dist, tiny) ** 2          # + 1e-12: equidistant guides still blend
        w /= w.sum(axis=1, keepdims=True)
        sc = lengths[a:a + _CHUNK, None] * s[None, :]                                  # (n, P)
        at = _shape_at(shapes[idx], sc)                                                 # (n, k, P, 3)
        blend = q[:, None] + np.einsum("nk,nkpx->npx", w, at)
        nearest = g_roots[idx[:, 0]][:, None] + at[:, 0]
        pull = (clump * sc ** 2)[..., None]
        out[a:a + _CHUNK] = blend + pull * (nearest - blend)
    return out


def axial_records(rows: np.ndarray, depth: np.ndarray, seed: int = SEED) -> np.ndarray:
    """One instance record per row (rows, 6) for fibers that are their rows' own axes: d = depth x the row's
    unit axis (|d| is what the shader reads as depth in the container), [t0, t1] the t at which
    p0 + t (p1 - p0) + w(t) d meets p0 and p1, w(t) = r0 + t (r1 - r0). ``depth`` is per strand (column 19)."""
    rows = np.asarray(rows, np.float64)
    strand = rows[:, 19].astype(np.int64)
    axis = rows[:, 4:7] - rows[:, 0:3]
    h = np.linalg.norm(axis, axis=1)
    ez = axis / h[:, None]
    r0, r1 = rows[:, 3], rows[:, 7]
    dep = np.asarray(depth, np.float64)[strand]
    # along the axis, P(t) sits at z(t) = t h + (r0 + t (r1 - r0)) dep: solve z = 0 and z = h
    # a piece shorter than its radius needs |t| > 1 (Curly's coils: pieces of 0.17 R, |t| ~ 6); float16
    # keeps |t| <= 1000 to 2^-11 relative, a position error of half a piece there, which is 1/2000 of the
    # radius. A piece shorter still gets the depth that keeps |t0| <= 1000 (shading only; the ribbon stays)
    dep = np.minimum(dep, 1000.0 * h / np.maximum(np.maximum(r0, r1), 1e-300))
    den = h + (r1 - r0) * dep
    with np.errstate(divide="ignore", invalid="ignore"):
        t0 = -r0 * dep / den
        t1 = (h - r0 * dep) / den
    bad = ~(np.isfinite(t0) & np.isfinite(t1) & (np.abs(t0) < 2048.0) & (np.abs(t1) < 2048.0) & (den > 0))
    t0, t1, dep = np.where(bad, 0.0, t0), np.where(bad, 1.0, t1), np.where(bad, 0.0, dep)
    half = np.empty((len(rows), 5), np.float16)
    half[:, 0:3] = dep[:, None] * ez
    half[:, 3] = t0
    half[:, 4] = t1
    out = np.empty((len(rows), 6), np.uint16)
    out[:, :5] = half.view(np.uint16)
    rng = np.random.default_rng(seed + 1)
    look = rng.integers(0, 256, (len(depth), 2)).astype(np.uint16)[strand]
    out[:, 5] = look[:, 0] | (look[:, 1] << np.uint16(8))
    return out


def _interpolated_rows(children: np.ndarray, R: float, tip_width: float, origin: np.ndarray) -> np.ndarray:
    """Container rows of every child, float32, child index in column 19, built a chunk at a time (float64
    rows of 8M pieces would be 1.3 GB)."""
    from ..scene.grooms import container_rows

    N, P = children.shape[:2]
    out = np.empty((N * (P - 1), 20), np.float32)
    for a in range(0, N, _CHUNK):
        c = children[a:a + _CHUNK]
        rows = container_rows(c, np.full(len(c), R), 1.0 - tip_width, origin)
        rows[:, 19] += a
        out[a * (P - 1):(a + len(c)) * (P - 1)] = rows
    return out


def build(p: Params, virtual_scene: Scene, *, max_instances: int = MAX_INSTANCES, seed: int = SEED,
          method: str = "interpolated", tip_taper: float = 0.0, clump: float = CLUMP,
          length_variation: float = LENGTH_VARIATION, tip_width: float = TIP_WIDTH,
          k: int = K_GUIDES) -> Reference:
    """The reference strands of the groom ``p["scene.groom_file"]`` beside its virtual scene under ``p``
    (whose container radius and origin it takes, and whose fiber count it matches, see the module).

    ``method``: ``"interpolated"`` (children blended from their ``k`` nearest guides, k = 1: each copies its
    nearest guide; ``clump``, ``length_variation`` and ``tip_width`` shape them), ``"strands"`` (the file's
    strands alone, as one fiber each, ``MAX_WIDENED_RADIUS`` R wide) or ``"disc"`` (children in a disc of
    radius R around each strand; ``tip_taper`` (0 .. 1) shrinks their offset linearly to (1 - tip_taper) R at
    the tip, so they gather toward the strand's tip, Blender's Clump)."""
    if method not in METHODS:
        raise ValueError(f"strand reference: method {method!r}; choose one of {', '.join(METHODS)}")
    for name, v in (("tip_taper", tip_taper), ("clump", clump), ("length_variation", length_variation),
                    ("tip_width", tip_width)):
        if not 0.0 <= v <= 1.0:
            raise ValueError(f"strand reference: {name} = {v:g}; it must be in 0 .. 1")
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
    R = float(np.median(virtual_scene.segments[:, 3]))
    F = ring_layout(p).fibers_per_container
    virtual_fibers = F * virtual_scene.n_guides
    fiber_radius = float(p["fibers.fiber_radius"])
    strands = [groom.strands[i] for i in keep]
    if method == "disc":
        polylines = resample_many(strands, n_seg)
        ok = (np.linalg.norm(np.diff(polylines, axis=1), axis=2) > 0).all(axis=1)
        polylines = polylines[ok]                   # a strand folded onto itself at n_seg pieces: left out
        S = len(polylines)
        rows = container_rows(polylines, np.full(S, R), tip_taper, virtual_scene.origin).astype(np.float32)
        per_strand = max(1, round(virtual_fibers / S))
        children = int(min(per_strand, max(1, max_instances // max(1, len(rows)))))
        if children < per_strand:
            fiber_radius = min(MAX_WIDENED_RADIUS, fiber_radius * per_strand / children)
        records = child_records(rows, child_offsets(S, children, seed), seed)
        scene = Scene(rows, virtual_scene.origin, f"{groom.path.stem} strands", S)
        return Reference(scene, records, S, n_seg, S * children, children, fiber_radius, virtual_fibers,
                         children < per_strand, "disc", tip_taper=tip_taper)

    # interpolated: guides on a common arc-length parameter fine enough for the length variation, whose
    # every (fine / n_seg)-th sample is the strand resampled to n_seg pieces (so a guide drawn is itself)
    fine = n_seg * int(np.ceil(GUIDE_SAMPLES / n_seg))
    guides = resample_guides(strands, fine)
    S = len(guides)
    wanted = max(S, virtual_fibers)
    total = int(max(S, min(wanted, max_instances // n_seg)))
    if method == "strands":
        # every child i < S is guide i itself (child_roots, interpolate): the file's strands and nothing else
        total, fiber_radius, length_variation, tip_width, clump = S, MAX_WIDENED_RADIUS, 0.0, 1.0, 0.0
    elif total < wanted:
        fiber_radius = min(MAX_WIDENED_RADIUS, fiber_radius * wanted / total)
    roots, parents = child_roots(guides, total, seed)
    rng = np.random.default_rng(seed + 2)
    frac = 1.0 - length_variation * rng.random(total)
    frac[:S] = 1.0
    depth = np.ones(total)                          # on the wall: see the module (how it is drawn)
    if k < 1:
        raise ValueError(f"strand reference: k = {k}; it must be at least 1")
    kids = interpolate(guides, roots, n_seg, parents=parents, k=k, clump=clump, lengths=frac)
    ok = (np.linalg.norm(np.diff(kids, axis=1), axis=2) > 1e-12 * max(R, 1e-300)).all(axis=1)
    ok &= np.isfinite(kids).all(axis=(1, 2))
    kids, depth = kids[ok], depth[ok]
    rows = _interpolated_rows(kids, R, tip_width, virtual_scene.origin)
    records = axial_records(rows, depth, seed)
    scene = Scene(rows, virtual_scene.origin, f"{groom.path.stem} interpolated strands", len(kids))
    return Reference(scene, records, S, n_seg, len(kids), 1, fiber_radius, virtual_fibers,
                     method != "strands" and total < wanted, method, clump=clump,
                     length_variation=length_variation, tip_width=tip_width,
                     dropped=int((~ok).sum()))


def render(ctx, ref: Reference, p: Params, cam: Camera, size: tuple[int, int],
           explicit: ExplicitRenderer | None = None) -> Frame:
    """The reference frame (colour and ids) through the explicit baseline's ribbons."""
    e = explicit or ExplicitRenderer(ctx)
    e.set_fibers(ref.scene, ref.records, ref.fibers_per_row, ref.fiber_radius)
    try:
        return e.render(p, cam, size, outputs=("color", "ids"))
    finally:
        if explicit is None:
            e.release()
            e.release_targets()
