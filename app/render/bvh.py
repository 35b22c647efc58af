"""A bounding-volume hierarchy over the container segments, so each pixel's ray meets only the containers
along it, nearest first (glsl/geometry/bvh.glsl walks it).

Why a hierarchy and not more proxy passes: on llvmpipe, rasterising harolongo's 158,100 proxies costs
~135 ms of vertex work and ~340 ms of raster with a constant-colour shader before any fiber is tested
(docs/performance.md, "Two ways to find a pixel's containers"), so any design that draws every proxy once
or more per frame (visibility buffer, k-buffer, depth peeling) costs its overlapping containers. The walk
costs a pixel the nodes its ray passes, and the shader stops as soon as the next container starts behind
the nearest fiber found.

The tree is an implicit complete binary tree (node i has children 2i + 1 and 2i + 2) over the segments,
ordered by median splits, so the shader needs no child pointers and no stack: it keeps one bit per level
for "far child still to visit" (bvh.glsl). Leaf j is sorted segment j (leaves past the last segment hold
nothing). A leaf is bounded by its container's bounding cylinder (the radius max(r0, r1) between the
leaning joint planes): segments are ~15 times longer than wide in real grooms, so a box around a
diagonal one is mostly empty. An inner node is bounded by a 14-DOP, the slabs along the three axes and
the four body diagonals (DOP_DIRECTIONS): a box is a 6-DOP, and around bundles of diagonal strands it
holds much empty space in front of the hair that rays enter before their fiber (harolongo: 78 walk steps
a hit pixel with boxes, 48 with 14-DOPs, counted in numpy with the nearest fiber known). The ray's
position and reciprocal direction along each direction are taken once per walk, so a slab costs what a
box axis costs.

The shader reads a node's children together (one step tests both), so the bounds are stored by parent:
record i + 1 holds node i's two children's bounds (record 0 the root's), 16 uint32 a record. A DOP is
7 pairs of 16-bit fixed-point bounds on a grid per direction (dop_base + q * dop_step, rounded outward
by a step), 7 uint32; a leaf's cylinder is 8 float32 (base, radius, unit axis, length). Nothing here
grows with the fiber count.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import VfiberError
from ..scene.containers import Scene, joint_slope

EPS_BOUND = 1e-4           # glsl/common/epsilon.glsl: the relative slack of every bounding volume


# The 14-DOP's directions (bvh.glsl: DOP_DIR), in float32 as the shader has them: the slabs are computed
# along the very directions the shader projects the ray on.
_DIRECTIONS = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1], [1, -1, 1], [1, 1, -1], [1, -1, -1]], np.float64)
DOP_DIRECTIONS = (_DIRECTIONS / np.linalg.norm(_DIRECTIONS, axis=1)[:, None]).astype(np.float32).astype(np.float64)
DOP_BITS = 16
DOP_MAX = (1 << DOP_BITS) - 1
RECORD_UINTS = 16          # four uvec4 a record (renderer.py: the hierarchy image, rgba32ui)
# The walk finds the deepest pending level of its trail from a float's exponent, exact below bit 24
# (bvh.glsl: trail_msb), so a tree has at most 2^24 leaves.
MAX_LEAVES = 1 << 24


class HierarchyTooLarge(VfiberError, MemoryError):
    """More container segments than the walk's hierarchy holds."""


@dataclass(frozen=True)
class ContainerBvh:
    records: np.ndarray     # (P, 16) uint32: record 0 the root's bound, record i + 1 node i's two children's:
                            # DOPs (uint32 0-6 left, 7-13 right: q_lo | q_hi << 16 per direction) above the
                            # leaves, cylinders (float32 bits 0-7 left, 8-15 right) for leaves
    order: np.ndarray       # (n,) uint32: the scene's segment index at each sorted position (leaf)
    leaves: int             # P >= n, a power of two; leaf j is node P - 1 + j
    dop_base: np.ndarray    # (7,) float32: a DOP bound q along direction k is dop_base[k] + q * dop_step[k]
    dop_step: np.ndarray    # (7,) float32

    @property
    def depth(self) -> int:
        return int(self.leaves).bit_length() - 1

    @property
    def nbytes(self) -> int:
        return int(self.records.nbytes + self.order.nbytes)


def bvh_words(n_segments: int) -> tuple[int, int]:
    """How many uvec4 words the hierarchy over n segments holds (build_bvh's records) and how many
    leaf-order entries, without building it."""
    leaves = 1
    while leaves < n_segments:
        leaves *= 2
    return leaves * RECORD_UINTS // 4, max(n_segments, 1)


def segment_cylinders(segments: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each container segment's bounding cylinder, float64: base point a, unit axis ez, length and radius.
    It holds the container's bounding volume of container.glsl (radius max(r0, r1) between the planes
    z = zLo and z = zHi that the leaning joint planes reach), padded for float32 rounding in the shader."""
    seg = segments.astype(np.float64)
    p0, p1 = seg[:, 0:3], seg[:, 4:7]
    axis = p1 - p0
    h = np.linalg.norm(axis, axis=1)
    ez = axis / np.maximum(h, 1e-300)[:, None]

    r_bound = np.maximum(seg[:, 3], seg[:, 7])
    z_lo = -r_bound * joint_slope((seg[:, 8:11] * ez).sum(1))
    z_hi = h + r_bound * joint_slope((seg[:, 12:15] * ez).sum(1))
    scale = np.abs(p0).max(1) + h + r_bound
    pad = 8.0 * EPS_BOUND * r_bound + 1e-6 * scale + 1e-30
    return p0 + ez * (z_lo - pad)[:, None], ez, (z_hi - z_lo) + 2.0 * pad, r_bound * (1.0 + 8.0 * EPS_BOUND) + pad


def segment_boxes(segments: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned boxes (lo, hi), float64, around each container segment's bounding cylinder."""
    a, ez, length, r = segment_cylinders(segments)
    b = a + ez * length[:, None]
    # a disc of radius r about an axis ez reaches r sqrt(1 - ez_k^2) along world axis k
    reach = r[:, None] * np.sqrt(np.maximum(0.0, 1.0 - ez * ez))
    lo, hi = np.minimum(a, b) - reach, np.maximum(a, b) + reach
    # float32 rounding in the shader: widen by a relative and an absolute hair
    pad = EPS_BOUND * (np.abs(lo) + np.abs(hi) + r[:, None]) + 1e-30
    return lo - pad, hi + pad


def _morton_codes(points: np.ndarray) -> np.ndarray:
    """30-bit Morton codes of points in their own bounding box."""
    lo, hi = points.min(0), points.max(0)
    q = np.clip((points - lo) / np.maximum(hi - lo, 1e-30) * 1023.0, 0, 1023).astype(np.uint32)

    def spread(x: np.ndarray) -> np.ndarray:
        x = x & 0x3FF
        x = (x | (x << 16)) & 0x030000FF
        x = (x | (x << 8)) & 0x0300F00F
        x = (x | (x << 4)) & 0x030C30C3
        return (x | (x << 2)) & 0x09249249

    return (spread(q[:, 0]) << 2) | (spread(q[:, 1]) << 1) | spread(q[:, 2])


def median_order(centroids: np.ndarray, leaves: int) -> np.ndarray:
    """Leaf order of a complete tree built top-down: every node splits its segments at the median of their
    centroids along the axis where they spread most and gives each child half its leaf slots (slots past
    the last segment stay empty, at the end of their node). One partition per level for all nodes of the
    level (argpartition: only the split matters, not the order inside each half)."""
    n = len(centroids)
    slots = np.full(leaves, -1, np.int64)
    slots[:n] = np.argsort(_morton_codes(centroids), kind="stable")     # a good start: fewer moves
    size = leaves
    while size > 1:
        k = leaves // size
        real = (slots >= 0).reshape(k, size)
        c = centroids[np.maximum(slots, 0)].reshape(k, size, 3)
        # each node's slots are contiguous: its centroid bounds are a reduction over a reshape
        lo = np.where(real[..., None], c, np.inf).min(1)
        hi = np.where(real[..., None], c, -np.inf).max(1)
        spread = np.where(np.isfinite(hi - lo), hi - lo, -1.0)
        axis = np.argmax(spread, axis=1)
        key = np.where(real, np.take_along_axis(c, axis[:, None, None], 2)[..., 0], np.inf)
        part = np.argsort(key, axis=1, kind="stable") if size == 2 else np.argpartition(key, size // 2 - 1, axis=1)
        slots = np.take_along_axis(slots.reshape(k, size), part, 1).reshape(-1)
        size //= 2
    return slots[:n]


def cylinder_dops(a: np.ndarray, ez: np.ndarray, length: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each cylinder's extent along DOP_DIRECTIONS, float64 (n, 7) lo and hi: its two end discs (centre c,
    normal ez, radius r) reach c . n +- r sqrt(1 - (ez . n)^2) along a direction n."""
    cos = ez @ DOP_DIRECTIONS.T
    reach = r[:, None] * np.sqrt(np.maximum(0.0, 1.0 - cos * cos))
    z0 = a @ DOP_DIRECTIONS.T
    z1 = (a + ez * length[:, None]) @ DOP_DIRECTIONS.T
    return np.minimum(z0, z1) - reach, np.maximum(z0, z1) + reach


def quantize_dops(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """16-bit fixed-point DOP bounds on one grid per direction, rounded outward by a further step (the
    shader's float32 decode and its float32 directions stay inside that margin). Rows with lo > hi (empty
    nodes) get q_lo = DOP_MAX, q_hi = 0. Returns q_lo, q_hi (uint32) and the grid's base and step (float32)."""
    full = lo[:, 0] <= hi[:, 0]
    if full.any():
        bottom, top = lo[full].min(0), hi[full].max(0)
    else:
        bottom = top = np.zeros(lo.shape[1])
    span = np.maximum(top - bottom, 1e-30 + 1e-7 * np.abs(top))
    step = (span / (DOP_MAX - 6) * (1.0 + 1e-5)).astype(np.float32)
    base = (bottom - 3.0 * step.astype(np.float64)).astype(np.float32)
    b64, s64 = base.astype(np.float64), step.astype(np.float64)
    with np.errstate(invalid="ignore"):
        q_lo = np.clip(np.floor((lo - b64) / s64) - 1.0, 0, DOP_MAX)
        q_hi = np.clip(np.ceil((hi - b64) / s64) + 1.0, 0, DOP_MAX)
    q_lo = np.where(full[:, None], q_lo, DOP_MAX).astype(np.uint32)
    q_hi = np.where(full[:, None], q_hi, 0).astype(np.uint32)
    return q_lo, q_hi, base, step


def build_bvh(scene: Scene) -> ContainerBvh:
    """The hierarchy over ``scene``'s segments: leaf order by median splits, then DOPs bottom-up, stored
    by parent (records)."""
    n = scene.n_segments
    if n > MAX_LEAVES:
        raise HierarchyTooLarge(f"{scene.name}: {n:,} container segments; the walk's hierarchy holds at most "
                                f"{MAX_LEAVES:,} (group the strands with scene.groom_cluster, or sample fewer)")
    lo, hi = segment_boxes(scene.segments)
    leaves = 1
    while leaves < n:
        leaves *= 2
    order = median_order(0.5 * (lo + hi), leaves).astype(np.uint32)
    a, ez, length, r = segment_cylinders(scene.segments[order])
    # leaves past the last segment are empty (lo > hi; a cylinder of radius -1 no ray enters)
    leaf_lo = np.full((leaves, 7), np.inf)
    leaf_hi = np.full((leaves, 7), -np.inf)
    leaf_lo[:n], leaf_hi[:n] = cylinder_dops(a, ez, length, r)
    levels_lo, levels_hi = [leaf_lo], [leaf_hi]
    while len(levels_lo[-1]) > 1:
        levels_lo.append(levels_lo[-1].reshape(-1, 2, 7).min(1))
        levels_hi.append(levels_hi[-1].reshape(-1, 2, 7).max(1))
    # heap order, root first, leaves last; the leaves' own DOPs are not stored (their cylinders are)
    inner_lo = np.concatenate(levels_lo[::-1])[:leaves - 1]
    inner_hi = np.concatenate(levels_hi[::-1])[:leaves - 1]
    q_lo, q_hi, base, step = quantize_dops(inner_lo, inner_hi)
    dops = q_lo | (q_hi << np.uint32(16))                     # (leaves - 1, 7): node i's DOP
    cyl = np.zeros((leaves, 8), np.float32)
    cyl[:, 3] = -1.0
    cyl[:n, 0:3], cyl[:n, 3], cyl[:n, 4:7], cyl[:n, 7] = a, r, ez, length
    cyl_bits = cyl.view(np.uint32)
    records = np.zeros((leaves, RECORD_UINTS), np.uint32)
    # record 0: the root's own bound (a tree of one leaf: its cylinder)
    if leaves == 1:
        records[0, 0:8] = cyl_bits[0]
    else:
        records[0, 0:7] = dops[0]
    # record i + 1: node i's children 2i + 1, 2i + 2
    parents = np.arange(leaves - 1)
    inner_parents = parents[2 * parents + 2 < leaves - 1]       # children inner nodes
    leaf_parents = parents[2 * parents + 1 >= leaves - 1]       # children leaves
    records[inner_parents + 1, 0:7] = dops[2 * inner_parents + 1]
    records[inner_parents + 1, 7:14] = dops[2 * inner_parents + 2]
    records[leaf_parents + 1, 0:8] = cyl_bits[2 * leaf_parents + 1 - (leaves - 1)]
    records[leaf_parents + 1, 8:16] = cyl_bits[2 * leaf_parents + 2 - (leaves - 1)]
    return ContainerBvh(records=records, order=order, leaves=leaves, dop_base=base, dop_step=step)


def decoded_bounds(bvh: ContainerBvh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The bounds the shader reads, float64, per node in heap order: DOP lo and hi ((2P - 1, 7); leaves
    and empty nodes lo = inf, hi = -inf) and per leaf its cylinder ((P, 8): base, radius, axis, length).
    For the numpy walks of the tests."""
    P = bvh.leaves
    lo = np.full((2 * P - 1, 7), np.inf)
    hi = np.full((2 * P - 1, 7), -np.inf)
    cyl = np.zeros((P, 8))
    cyl[:, 3] = -1.0
    base, step = bvh.dop_base.astype(np.float64), bvh.dop_step.astype(np.float64)

    def dop(words: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        q_lo, q_hi = (words & 0xFFFF).astype(np.float64), (words >> 16).astype(np.float64)
        full = (q_lo[:, :1] <= q_hi[:, :1])
        return np.where(full, base + q_lo * step, np.inf), np.where(full, base + q_hi * step, -np.inf)

    def put(node: np.ndarray, dop_words: np.ndarray, cyl_words: np.ndarray) -> None:
        leaf = node >= P - 1
        if (~leaf).any():
            lo[node[~leaf]], hi[node[~leaf]] = dop(dop_words[~leaf])
        cyl[node[leaf] - (P - 1)] = np.ascontiguousarray(cyl_words[leaf]).view(np.float32)

    put(np.array([0]), bvh.records[0:1, 0:7], bvh.records[0:1, 0:8])
    parents = np.arange(P - 1)
    put(2 * parents + 1, bvh.records[parents + 1, 0:7], bvh.records[parents + 1, 0:8])
    put(2 * parents + 2, bvh.records[parents + 1, 7:14], bvh.records[parents + 1, 8:16])
    return lo, hi, cyl
