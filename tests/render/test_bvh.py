"""The container hierarchy (app/render/bvh.py) bounds what it should, and its walk (glsl/geometry/bvh.glsl,
mirrored here in numpy step for step, on the bounds the shader decodes) visits exactly the containers whose
bounding cylinder a ray enters."""

from __future__ import annotations

import numpy as np
import pytest

from app.params import Params
from app.render.bvh import (
    DOP_DIRECTIONS, DOP_MAX, build_bvh, cylinder_dops, decoded_bounds, segment_cylinders,
)
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


def _dop_interval(lo, hi, o, d):
    """[enter, exit] of o + t d through the slabs lo <= x . n <= hi along DOP_DIRECTIONS."""
    on, dn = DOP_DIRECTIONS @ o, DOP_DIRECTIONS @ d
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / np.where(dn == 0.0, 1e-30, dn)
    ta, tb = (lo - on) * inv, (hi - on) * inv
    return np.minimum(ta, tb).max(), np.maximum(ta, tb).min()


def _walk(bvh, o, d, t_near=0.0):
    """bvh.glsl's walk_to_leaf and pop with no cut, on the decoded records: the leaves it stands on."""
    lo, hi, cyl = decoded_bounds(bvh)
    depth, first = bvh.depth, bvh.leaves - 1

    def bound(i):
        if i >= first:
            c = cyl[i - first]
            if c[3] < 0:
                return np.inf, -np.inf
            return _cylinder_interval(c[0:3], c[4:7], c[7], c[3], o, d)
        if not lo[i, 0] <= hi[i, 0]:
            return np.inf, -np.inf
        return _dop_interval(lo[i], hi[i], o, d)

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
    node, trail = 0, 0          # the root's own bound is not tested: its children's tests cover it
    while node is not None:
        if level(node) == depth:
            visited.append(int(bvh.order[node - first]))
            node, trail = pop(node, trail)
            continue
        left = 2 * node + 1
        lv, rv = bound(left), bound(left + 1)
        in_l, in_r = entered(lv), entered(rv)
        if in_l and in_r:
            trail |= 1 << level(node)
        if in_l or in_r:
            node = left if in_l and (not in_r or lv[0] <= rv[0]) else left + 1
        else:
            node, trail = pop(node, trail)
    return visited


@pytest.mark.parametrize("n,seed", [(1, 1), (5, 2), (37, 3), (200, 4)])
def test_dops_hold_their_subtrees_and_cylinders_their_containers(n, seed):
    scene = _scene(n, seed)
    bvh = build_bvh(scene)
    assert sorted(bvh.order.tolist()) == list(range(scene.n_segments))
    a, ez, length, r = segment_cylinders(scene.segments)
    seg = scene.segments.astype(np.float64)
    # the segment's end discs lie inside its cylinder
    for end, rad in ((seg[:, 0:3], seg[:, 3]), (seg[:, 4:7], seg[:, 7])):
        z = ((end - a) * ez).sum(1)
        assert ((z > 0) & (z < length)).all() and (rad < r).all()
    lo, hi, cyl = decoded_bounds(bvh)
    first = bvh.leaves - 1
    n = scene.n_segments
    # each leaf holds its segment's cylinder, in float32; leaves past the last segment are empty
    k = bvh.order.astype(np.int64)
    np.testing.assert_array_equal(cyl[:n, 0:3], a[k].astype(np.float32))
    np.testing.assert_array_equal(cyl[:n, 3], r[k].astype(np.float32))
    np.testing.assert_array_equal(cyl[:n, 7], length[k].astype(np.float32))
    assert (cyl[n:, 3] < 0).all()
    # every inner node's DOP holds, in float64, the exact DOP of every cylinder below it (read back from
    # the float32 words the shader reads), with a margin
    leaf_lo, leaf_hi = cylinder_dops(cyl[:n, 0:3], cyl[:n, 4:7], cyl[:n, 7], cyl[:n, 3])
    for i in range(first):
        below, size = i, 1
        while below < first:
            below, size = 2 * below + 1, size * 2
        j = np.arange(below - first, below - first + size)
        j = j[j < n]
        if len(j) == 0:
            assert not lo[i, 0] <= hi[i, 0], f"node {i} holds nothing and must be empty"
            continue
        margin = bvh.dop_step * 0.5
        assert (lo[i] <= leaf_lo[j].min(0) - margin).all() and (hi[i] >= leaf_hi[j].max(0) + margin).all(), i


def test_dop_grid_keeps_every_bound_inside_its_range():
    scene = _scene(300, 9)
    bvh = build_bvh(scene)
    inner = bvh.records[1:, 0:14][(2 * np.arange(bvh.leaves - 1) + 2 < bvh.leaves - 1)].reshape(-1, 7)
    q_lo, q_hi = inner & 0xFFFF, inner >> 16
    full = q_lo[:, 0] <= q_hi[:, 0]
    assert full.sum() > 100
    # an empty subtree (leaves past the last segment) is empty along every direction
    assert (q_lo[~full] == DOP_MAX).all() and (q_hi[~full] == 0).all()
    # one step of slack on either side of every bound (the outward rounding) never clips at the grid's ends
    assert q_lo[full].min() >= 1 and q_hi[full].max() <= DOP_MAX - 1
    assert (q_lo[full] <= q_hi[full]).all()


def test_a_dop_prunes_diagonal_bundles_a_box_cannot():
    """The reason for the 14-DOP (bvh.py): around a bundle of parallel diagonal strands a box holds empty
    space on both sides that the body-diagonal slabs cut away; a ray through that space enters the
    box but not the DOP."""
    t = np.linspace(0.0, 1.0, 9)
    a = np.stack([t, t, t], 1)[:-1]
    ez = np.tile(np.array([1.0, 1.0, 1.0]) / np.sqrt(3.0), (8, 1))
    length, r = np.full(8, np.sqrt(3.0) / 8), np.full(8, 0.01)
    lo, hi = cylinder_dops(a, ez, length, r)
    lo, hi = lo.min(0), hi.max(0)
    o, d = np.array([1.0, 0.0, 0.5]), np.array([0.0, 0.0, 1.0])     # up through a corner of the box
    assert _dop_interval(lo, hi, o, d)[0] > _dop_interval(lo, hi, o, d)[1]
    box_lo, box_hi = lo[:3], hi[:3]        # directions 0-2 are the axes: the bundle's box
    assert box_lo[0] <= o[0] <= box_hi[0] and box_lo[1] <= o[1] <= box_hi[1], "the ray passes through the box"


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


def test_a_scene_past_the_hierarchys_size_is_refused_with_a_message(monkeypatch):
    import app.render.bvh as bvh_module

    monkeypatch.setattr(bvh_module, "MAX_LEAVES", 8)
    with pytest.raises(bvh_module.HierarchyTooLarge, match="at most 8"):
        build_bvh(_scene(5, 1))                 # 15 segments


def test_trail_msb_is_findmsb_below_bit_24(ctx):
    """bvh.glsl's trail_msb takes the deepest pending level from a float's exponent; it must agree with
    findMSB for every trail a tree of at most 2^24 leaves can hold (bits 0-23)."""
    import moderngl

    from app.gl.shaders import ProgramCache

    rng = np.random.default_rng(3)
    values = np.concatenate([[0], 1 << np.arange(24), (1 << np.arange(1, 25)) - 1,
                             rng.integers(0, 1 << 24, 4000)]).astype(np.uint32)
    n = len(values)
    src = ProgramCache().expand("geometry/bvh.glsl")[0]
    fs = ("#version 450 core\n" + src + "\nuniform int uCount;\nlayout(std430, binding = 12) buffer V { uint v[]; };\n"
          "out vec4 o;\nvoid main() {\n  int i = int(gl_FragCoord.x);\n  uint t = v[min(i, uCount - 1)];\n"
          "  o = vec4(float(trail_msb(t)), float(findMSB(t)), 0.0, 1.0);\n}\n")
    vs = ("#version 450 core\nvoid main() { vec2 c = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));"
          " gl_Position = vec4(c * 2.0 - 1.0, 0.0, 1.0); }\n")
    prog = ctx.program(vertex_shader=vs, fragment_shader=fs)
    buf = ctx.buffer(values.tobytes())
    buf.bind_to_storage_buffer(12)
    fbo = ctx.framebuffer([ctx.texture((n, 1), 4, dtype="f4")])
    fbo.use()
    prog["uCount"].value = n
    ctx.vertex_array(prog, []).render(moderngl.TRIANGLES, vertices=3)
    out = np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32).reshape(n, 4)
    assert np.array_equal(out[:, 0], out[:, 1])
