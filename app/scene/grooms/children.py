"""Interpolated child guides (``scene.groom_children``): extra, thinner containers between the file's
strands, each a blend of its nearest strands' shapes, as Blender's "Interpolated" children and XGen's guide
interpolation make hair between guides.

Why containers and not fibers. A fiber sits at a fixed offset in its container's frame, carried along the
guide (an offset curve, like Blender's "Simple" children). Where a guide curls tighter than the container
is wide -- Curly_100: curls of radius 11 (median per strand) in containers of radius 17.5 -- the fibers
beyond the radius of curvature fold back on the inside of every bend, and each container draws a ball of
short, crossing pieces. Several thinner containers, each running along its own copy of the curl, do not
fold, and need nothing new in the fiber model: every renderer, the export and the float64 reference take
container rows as they are.

The children of a guide are rooted around its root, over a disc in the plane normal to its first piece
whose radius is the root's distance to its nearest neighbouring root (clipped to ``SPACING_CLIP`` x the
median, so a lone strand keeps its children near it). Roots are placed deterministically on a sunflower
(Vogel) spiral, evenly by area, turned per guide by a seeded angle so neighbouring discs do not line up.
Each child is its root plus the weighted blend of the root-relative shapes of its ``NEIGHBOURS`` nearest
guides at the same arc fraction (inverse-distance weights that fade to zero at the next guide out, so a
child moving between neighbourhoods changes shape continuously, and a child on a guide's root is that
guide). The guides themselves stay guides: children are added after them. A child whose blend folds at
the scene's segment count (curls of different phases nearly cancelling: a cusp) takes its nearest guide's
shape instead (:meth:`Children.settle`).

The children also narrow every container to 1 / sqrt(1 + children) of its radius (:func:`radius_scale`):
the same hair in more, thinner clumps. Whether a groom needs them, and how many, is
``fibers.groom_auto``'s call (``defaults.auto_children``: by how many joints fold).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .guides import _CHUNK_ELEMS, nearest_points, root_spacing

NEIGHBOURS = 4                 # guides blended per child (Blender's Interpolate Curves node: Max Neighbors)
CANDIDATES = 16                # a child's guides are sought among its own guide's nearest this many
GOLDEN_ANGLE = math.pi * (3.0 - math.sqrt(5.0))
MAX_CHILDREN = 31              # per guide (scene.groom_children's bound): 32 containers per strand


def _root_frames(guides: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors spanning the plane normal to each guide's first piece (its root-to-tip chord, or
    +Z, where that piece has no length)."""
    from ..containers import orthonormal_x

    d = guides[:, 1] - guides[:, 0]
    chord = guides[:, -1] - guides[:, 0]
    d = np.where((np.linalg.norm(d, axis=1) > 0)[:, None], d,
                 np.where((np.linalg.norm(chord, axis=1) > 0)[:, None], chord, [0.0, 0.0, 1.0]))
    z = d / np.linalg.norm(d, axis=1, keepdims=True)
    ex = orthonormal_x(z)
    return ex, np.cross(z, ex)


def child_roots(guides: np.ndarray, per_guide: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(roots (S * per_guide, 3), parent guide of each): ``per_guide`` roots around every guide's root, on
    a sunflower spiral over the disc of its local spacing, child-major (all guides' first child, then all
    second children ...), so a prefix of the children is spread over the whole groom."""
    S = len(guides)
    if per_guide < 1 or S == 0:
        return np.zeros((0, 3)), np.zeros(0, np.int64)
    ex, ey = _root_frames(guides)
    spacing = root_spacing(guides[:, 0])
    turn = np.random.default_rng(seed).random(S) * 2.0 * np.pi
    j = np.arange(1, per_guide + 1)
    # the guide is the spiral's point 0, at the centre; its children fill the rest evenly by area
    r = np.sqrt(j / (per_guide + 0.5))[:, None] * spacing[None, :]             # (per_guide, S)
    a = j[:, None] * GOLDEN_ANGLE + turn[None, :]
    roots = guides[None, :, 0] + (r * np.cos(a))[..., None] * ex[None] + (r * np.sin(a))[..., None] * ey[None]
    return roots.reshape(-1, 3), np.tile(np.arange(S), per_guide)


def blend(guides: np.ndarray, roots: np.ndarray, parents: np.ndarray,
          k: int = NEIGHBOURS) -> tuple[np.ndarray, np.ndarray]:
    """(children (N, M, 3), the guide nearest each) at ``roots`` among ``guides`` (S, M, 3), all on one
    arc-length parameter: each the
    root plus the weighted blend of the root-relative shapes of its ``k`` nearest guides (by root distance,
    among its parent's ``CANDIDATES`` nearest). Weight (1 - d / h)^2 / d^2, h the distance of the next guide
    out: continuous as a child moves between guides, and the guide itself where d = 0."""
    guides = np.asarray(guides, np.float64)
    S, M = guides.shape[:2]
    N = len(roots)
    g_roots = guides[:, 0]
    shapes = guides - g_roots[:, None]
    size = max(float(np.ptp(g_roots, axis=0).max()) if S else 0.0, 1e-300)
    tiny = 1e-12 * size
    kk = min(k, S)
    cand, _ = nearest_points(g_roots, g_roots, min(S, max(CANDIDATES, kk + 1)))
    out = np.empty((N, M, 3))
    nearest = np.empty(N, np.int64)
    step = max(1, _CHUNK_ELEMS // max(1, kk * M * 3))
    for a in range(0, N, step):
        q = roots[a:a + step]
        c = cand[parents[a:a + step]]                                          # (n, C)
        d = np.linalg.norm(g_roots[c] - q[:, None], axis=2)
        order = np.argsort(d, axis=1, kind="stable")
        d = np.take_along_axis(d, order, 1)
        c = np.take_along_axis(c, order, 1)
        # h: the next guide out; without one (S <= k) twice the farthest, so every guide keeps some weight
        h = d[:, kk] if d.shape[1] > kk else 2.0 * d[:, kk - 1] + tiny
        idx, dist = c[:, :kk], d[:, :kk]
        h = np.maximum(h, dist[:, -1] + tiny)[:, None]
        fall = (1.0 - dist / h) ** 2
        w = (fall + 1e-12) / np.maximum(dist, tiny) ** 2          # + 1e-12: equidistant guides still blend
        w /= w.sum(axis=1, keepdims=True)
        out[a:a + step] = q[:, None] + np.einsum("nk,nkmx->nmx", w, shapes[idx])
        nearest[a:a + step] = idx[:, 0]
    return out, nearest


@dataclass
class Children:
    """A groom's guides and their interpolated children on one arc-length parameter."""
    polylines: np.ndarray          # (S * (1 + per_guide), M, 3): the S guides first, unchanged
    parents: np.ndarray            # the guide each polyline stands for (itself for a guide)
    nearest: np.ndarray            # the guide whose root is nearest each polyline's root
    guides: int                    # S
    narrow: float                  # radius_scale: every container's radius is multiplied by this

    def settle(self, resampled: np.ndarray, max_turn: float) -> tuple[np.ndarray, int]:
        """``resampled`` (the polylines at the scene's segment count) with every child that folds there --
        a joint sharper than ``max_turn`` degrees or a piece of no length, where blending curls of different
        phases nearly cancels -- replaced by its nearest guide's shape moved to its root (no blend: the
        guide's own joints), and how many were. Guides are left as they are."""
        from .segments import joint_turns

        S = self.guides
        kids = resampled[S:]
        turns = joint_turns(kids)
        bad = (turns > max_turn).any(axis=1) if turns.size else np.zeros(len(kids), bool)
        bad |= ~(np.linalg.norm(np.diff(kids, axis=1), axis=2) > 0).all(axis=1)
        if not bad.any():
            return resampled, 0
        out = resampled.copy()
        i = S + np.flatnonzero(bad)
        g = self.nearest[i]
        out[i] = resampled[g] - resampled[g, :1] + resampled[i, :1]
        return out, int(bad.sum())


def with_children(guides: np.ndarray, per_guide: int, seed: int = 0) -> Children:
    """The guides (S, M, 3), on one arc-length parameter, and ``per_guide`` interpolated children of each
    (:func:`child_roots`, :func:`blend`), the radius scale included (:func:`radius_scale`)."""
    guides = np.asarray(guides, np.float64)
    S = len(guides)
    if per_guide < 1 or S == 0:
        return Children(guides, np.arange(S), np.arange(S), S, 1.0)
    roots, parents = child_roots(guides, per_guide, seed)
    kids, nearest = blend(guides, roots, parents)
    return Children(np.concatenate([guides, kids]), np.concatenate([np.arange(S), parents]),
                    np.concatenate([np.arange(S), nearest]), S, radius_scale(per_guide))


def radius_scale(per_guide: int) -> float:
    """How much the children narrow every container: 1 / sqrt(1 + per_guide), so a guide and its children
    together have the cross-section one container of the guide's radius had (the same hair, in thinner
    clumps). The root spacing would say less: children spread over neighbouring discs land close to one
    another now and then, and 0.75 x the median nearest distance stops narrowing past ~8 children (Curly_100:
    0.40 at 8, 0.36 at 15, against 0.33 and 0.25 here)."""
    return 1.0 / math.sqrt(1.0 + max(0, per_guide))


def common_parameter(polylines) -> np.ndarray:
    """Guides on the one arc-length parameter children are blended on: the polylines' own resolution (the
    most segments any has, at most 64), (S, n + 1, 3). Stacked as they are when they already share it."""
    from .guides import resample_many

    counts = [len(q) for q in polylines]
    n = int(min(64, max(1, max(counts) - 1)))
    if all(c == n + 1 for c in counts):
        return np.stack([np.asarray(q, np.float64) for q in polylines])
    return resample_many(polylines, n)


def curl_radius(strands) -> float:
    """How tightly a groom's strands curl: the median over strands of length / total turning (the radius
    of the circle that turns as much over the same length; straight strands: infinite). Curly_100: 11.4,
    against container radius 17.5; the other shared grooms 4-30x their container radius."""
    radii = []
    for s in strands:
        d = np.diff(np.asarray(s, np.float64), axis=0)
        length = np.linalg.norm(d, axis=1)
        d = d[length > 0] / length[length > 0, None]
        turn = float(np.arccos(np.clip((d[1:] * d[:-1]).sum(axis=1), -1.0, 1.0)).sum()) if len(d) > 1 else 0.0
        radii.append(length.sum() / turn if turn > 0 else math.inf)
    return float(np.median(radii)) if radii else math.inf
