"""A bounding-volume hierarchy over the container segments, so each pixel's ray meets only the containers
along it, nearest first (glsl/geometry/bvh.glsl walks it).

Why a hierarchy and not more proxy passes: on llvmpipe, rasterising harolongo's 158,100 proxies costs
~135 ms of vertex work and ~340 ms of raster with a constant-colour shader before any fiber is tested
(docs/performance.md, "Per-pixel container walk"), so any design that draws every proxy once or more per
frame (visibility buffer, k-buffer, depth peeling) costs its overlapping containers. The walk costs a
pixel the nodes its ray passes, and the shader stops as soon as the next container starts behind the
nearest fiber found.

The tree is an implicit complete binary tree (node i has children 2i + 1 and 2i + 2) over the segments
sorted along a Morton curve, so the shader needs no child pointers and no stack: it keeps one bit per
level for "far child still to visit" (bvh.glsl). Leaf j is sorted segment j (leaves past the last segment
hold nothing). Inner nodes store their box; a leaf stores its container's bounding cylinder instead (the
radius max(r0, r1) between the leaning joint planes), in the same two vec4: segments are ~15 times longer
than wide in real grooms (harolongo), so the box of a diagonal one is mostly empty and the cylinder
keeps the walk from handing over containers the ray misses. Two vec4 per node plus the segment order;
nothing here grows with the fiber count.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..scene.containers import Scene, joint_slope

EPS_BOUND = 1e-4           # glsl/common/epsilon.glsl: the relative slack of every bounding volume


@dataclass(frozen=True)
class ContainerBvh:
    nodes: np.ndarray       # (2 P - 1, 2, 4) float32, scene-relative: inner node: box lo.xyz, 0 | hi.xyz, 0;
                            # leaf: cylinder base a.xyz, radius | axis ez.xyz, length (radius < 0: empty)
    order: np.ndarray       # (n,) uint32: the scene's segment index at each sorted position (leaf)
    leaves: int             # P >= n, a power of two; leaf j is node P - 1 + j

    @property
    def depth(self) -> int:
        return int(self.leaves).bit_length() - 1

    @property
    def nbytes(self) -> int:
        return int(self.nodes.nbytes + self.order.nbytes)


def bvh_words(n_segments: int) -> tuple[int, int]:
    """How many vec4 words the hierarchy over n segments holds (build_bvh's nodes) and how many leaf-order
    entries, without building it."""
    leaves = 1
    while leaves < n_segments:
        leaves *= 2
    return 2 * (2 * leaves - 1), max(n_segments, 1)


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
    """Leaf order of a complete tree built top-down: every node sorts its segments along the axis where
    their centroids spread most and gives each child half its leaf slots (slots past the last segment
    stay empty, at the end of their node). One sort per level for all nodes of the level."""
    n = len(centroids)
    slots = np.full(leaves, -1, np.int64)
    slots[:n] = np.argsort(_morton_codes(centroids), kind="stable")     # a good start: fewer moves
    size = leaves
    while size > 1:
        node = np.arange(leaves) // size
        real = slots >= 0
        c = centroids[np.maximum(slots, 0)]
        # each node's slots are contiguous: its centroid bounds are a reduction over a reshape
        lo = np.where(real[:, None], c, np.inf).reshape(-1, size, 3).min(1)
        hi = np.where(real[:, None], c, -np.inf).reshape(-1, size, 3).max(1)
        spread = np.where(np.isfinite(hi - lo), hi - lo, -1.0)
        axis = np.argmax(spread, axis=1)
        key = np.where(real, c[np.arange(leaves), axis[node]], np.inf)
        slots = slots[np.lexsort((key, node))]
        size //= 2
    return slots[:n]


def build_bvh(scene: Scene) -> ContainerBvh:
    """The hierarchy over ``scene``'s segments: leaf order by median splits, then boxes bottom-up."""
    n = scene.n_segments
    lo, hi = segment_boxes(scene.segments)
    leaves = 1
    while leaves < n:
        leaves *= 2
    order = median_order(0.5 * (lo + hi), leaves).astype(np.uint32)
    lo, hi = lo[order], hi[order]
    # leaves past the last segment get an empty box (lo > hi) that no ray enters
    leaf_lo = np.full((leaves, 3), np.inf)
    leaf_hi = np.full((leaves, 3), -np.inf)
    leaf_lo[:n], leaf_hi[:n] = lo, hi
    levels_lo, levels_hi = [leaf_lo], [leaf_hi]
    while len(levels_lo[-1]) > 1:
        levels_lo.append(levels_lo[-1].reshape(-1, 2, 3).min(1))
        levels_hi.append(levels_hi[-1].reshape(-1, 2, 3).max(1))
    all_lo = np.concatenate(levels_lo[::-1])           # heap order: root first, leaves last
    all_hi = np.concatenate(levels_hi[::-1])
    nodes = np.zeros((2 * leaves - 1, 2, 4), np.float32)
    big = np.float32(3e38)
    # round outward to float32 so the stored box still holds the float64 one
    nodes[:, 0, :3] = np.nextafter(np.clip(all_lo, -big, big).astype(np.float32), -np.inf)
    nodes[:, 1, :3] = np.nextafter(np.clip(all_hi, -big, big).astype(np.float32), np.inf)
    # leaves: the cylinder instead of the box (an empty leaf: radius -1, no ray enters it)
    a, ez, length, r = segment_cylinders(scene.segments[order])
    leaf = nodes[leaves - 1:]
    leaf[:] = 0.0
    leaf[:, 0, 3] = -1.0
    leaf[:n, 0, :3], leaf[:n, 0, 3] = a, r
    leaf[:n, 1, :3], leaf[:n, 1, 3] = ez, length
    return ContainerBvh(nodes=nodes, order=order, leaves=leaves)
