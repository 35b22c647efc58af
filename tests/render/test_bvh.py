"""The container hierarchy (app/render/bvh.py) bounds what it should, and its walk (glsl/geometry/bvh.glsl,
mirrored here in numpy step for step) visits exactly the containers whose bounding cylinder a ray enters."""

from __future__ import annotations

import numpy as np
import pytest

from app.params import Params
from app.render.bvh import build_bvh, segment_boxes, segment_cylinders
from app.scene.generators import build_scene


def _scene(n: int, seed: int):
    p = Params({"scene.generator": "curved" if seed % 2 else "furball", "scene.count": n, "scene.seed": seed,
                "scene.segments": 3, "scene.bend": 40.0})
    return build_scene(p)


def _cylinder_interval(a, ez, length, r, o, d):
    """[enter, exit] of o + t d through the finite cylinder: float64, the bvh.glsl formulas."""
    oc = o - a
    oz, dz = oc @ ez, d @ ez
    op, dp = oc - oz * ez, d - dz * ez
    A, B, C = dp @ dp, op @ dp, op @ op - r * r
    if A == 0.0:
        t0, t1 = (-np.inf, np.inf) if C <= 0 else (np.inf, -np.inf)
    else:
        disc = B * B - A * C
        if disc < 0:
            return np.inf, -np.inf
        s = np.sqrt(disc)
        t0, t1 = (-B - s) / A, (-B + s) / A
    if dz == 0.0:
        z0, z1 = (-np.inf, np.inf) if 0.0 <= oz <= length else (np.inf, -np.inf)
    else:
        z0, z1 = sorted(((0.0 - oz) / dz, (length - oz) / dz))
    return max(t0, z0), min(t1, z1)


def _box_interval(lo, hi, o, d):
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / np.where(d == 0.0, 1e-30, d)
    ta, tb = (lo - o) * inv, (hi - o) * inv
    return np.minimum(ta, tb).max(), np.maximum(ta, tb).min()


def _walk(bvh, o, d, t_near=0.0):
    """bvh.glsl's walk_to_leaf and pop with no cut: the leaves it stands on, in order."""
    nodes = bvh.nodes.astype(np.float64)
    depth, first = bvh.depth, bvh.leaves - 1

    def bound(i, leaf):
        a, b = nodes[i]
        if leaf:
            if a[3] < 0:
                return np.inf, -np.inf
            return _cylinder_interval(a[:3], b[:3], b[3], a[3], o, d)
        if a[0] > b[0]:
            return np.inf, -np.inf
        return _box_interval(a[:3], b[:3], o, d)

    def entered(iv):
        return iv[0] <= iv[1] and iv[1] >= t_near

    def level(i):
        return (i + 1).bit_length() - 1

    def pop(node, trail):
        if trail == 0:
            return None, 0
        resume = trail.bit_length() - 1
        ancestor = ((node + 1) >> (level(node) - resume - 1)) - 1
        far = ancestor + 1 if ancestor & 1 else ancestor - 1
        return far, trail & ~(1 << resume)

    visited = []
    node, trail = (0, 0) if entered(bound(0, depth == 0)) else (None, 0)
    while node is not None:
        if level(node) == depth:
            visited.append(int(bvh.order[node - first]))
            node, trail = pop(node, trail)
            continue
        left = 2 * node + 1
        leaves = level(node) + 1 == depth
        lv, rv = bound(left, leaves), bound(left + 1, leaves)
        in_l, in_r = entered(lv), entered(rv)
        if in_l and in_r:
            trail |= 1 << level(node)
        if in_l or in_r:
            node = left if in_l and (not in_r or lv[0] <= rv[0]) else left + 1
        else:
            node, trail = pop(node, trail)
    return visited


@pytest.mark.parametrize("n,seed", [(1, 1), (5, 2), (37, 3), (200, 4)])
def test_boxes_hold_their_children_and_cylinders_their_containers(n, seed):
    scene = _scene(n, seed)
    bvh = build_bvh(scene)
    assert sorted(bvh.order.tolist()) == list(range(scene.n_segments))
    a, ez, length, r = segment_cylinders(scene.segments)
    seg = scene.segments.astype(np.float64)
    # the segment's end discs lie inside its cylinder
    for end, rad in ((seg[:, 0:3], seg[:, 3]), (seg[:, 4:7], seg[:, 7])):
        z = ((end - a) * ez).sum(1)
        assert ((z > 0) & (z < length)).all() and (rad < r).all()
    lo, hi = segment_boxes(scene.segments)
    first = bvh.leaves - 1
    for i in range(first):
        for c in (2 * i + 1, 2 * i + 2):
            if c >= first:
                j = c - first
                if j >= scene.n_segments:
                    continue
                c_lo, c_hi = lo[bvh.order[j]], hi[bvh.order[j]]
            else:
                c_lo, c_hi = bvh.nodes[c, 0, :3], bvh.nodes[c, 1, :3]
                if c_lo[0] > c_hi[0]:
                    continue
            assert (bvh.nodes[i, 0, :3] <= c_lo).all() and (bvh.nodes[i, 1, :3] >= c_hi).all(), (i, c)


@pytest.mark.parametrize("n,seed", [(1, 5), (6, 6), (64, 7), (300, 8)])
def test_walk_visits_exactly_the_containers_the_ray_enters(n, seed):
    scene = _scene(n, seed)
    bvh = build_bvh(scene)
    a, ez, length, r = segment_cylinders(scene.segments)
    lo, hi = scene.bounds()
    centre, size = 0.5 * (lo + hi) - scene.origin, float(np.linalg.norm(hi - lo))
    rng = np.random.default_rng(seed)
    hits = 0
    for _ in range(300):
        o = centre + rng.normal(size=3) * size
        k = rng.integers(scene.n_segments)                     # half the rays aimed at a container
        aimed = a[k] + ez[k] * length[k] * rng.random() + rng.normal(size=3) * r[k]
        target = aimed if rng.random() < 0.5 else centre + (rng.random(3) - 0.5) * size * 0.6
        d = (target - o) / np.linalg.norm(target - o)
        expected = {i for i in range(scene.n_segments)
                    if (iv := _cylinder_interval(a[i], ez[i], length[i], r[i], o, d))[0] <= iv[1] and iv[1] >= 0}
        visited = _walk(bvh, o, d)
        assert len(visited) == len(set(visited)), "a container is visited twice"
        assert set(visited) == expected
        hits += bool(expected)
    assert hits > 100, "the rays should meet containers"
