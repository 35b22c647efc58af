"""The per-pixel container walk on real grooms (issue 12): exact mode equals brute force in every pixel of
the densest crop of harolongo, sintel and Ratboy; fast mode differs only where it names a fiber behind
the nearest; and on random rays the walk's winner is the float64 reference's nearest fiber over every
container the ray could meet, found without the hierarchy.

The grooms are read in place from ``../shared/hair-data`` (skipped when it is missing). Each crop is the
block of the frame whose pixels enter the most containers (from the cost output), so the walk goes deep
there: many containers per ray, several draws per pixel.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from app import reference
from app.cli import resolve_params
from app.render.bvh import segment_cylinders
from app.render.camera import Camera
from app.scene.generators import build_scene
from tests.support.paths import HAIR_DATA

DATA = HAIR_DATA
needs_data = pytest.mark.skipif(not DATA.is_dir(), reason=f"shared hair data not found at {DATA}")
GROOMS = ("harolongo.data", "sintel_hair.tfx", "Ratboy_mohawk.tfx")
SIZE = (320, 180)
CROP = (24, 16)          # brute force tests every fiber of every container the walk reaches


@pytest.fixture(scope="module")
def grooms():
    """name -> (params, scene, camera): built once for the module (harolongo takes seconds)."""
    out = {}
    for name in GROOMS:
        p, _ = resolve_params(str(DATA / name), ["quality.visibility=walk"])     # the walk, whatever auto says
        scene = build_scene(p)
        out[name] = (p, scene, Camera.from_params(p, scene, aspect=SIZE[0] / SIZE[1]))
    return out


@pytest.fixture(scope="module")
def frames(grooms, ctx):
    """name -> the exact frame (ids, geom, cost) of the whole view, and a renderer holding its scene."""
    from app.render.renderer import Renderer

    out = {}
    for name, (p, scene, cam) in grooms.items():
        r = Renderer(ctx)
        r.set_scene(scene)
        out[name] = (r, r.render(p, cam, SIZE, outputs=("ids", "geom", "cost"), mode="exact"))
    yield out
    for r, _ in out.values():
        r.release_targets()


def densest_crop(cost: np.ndarray) -> tuple[tuple[int, int, int, int], tuple[slice, slice]]:
    """The CROP-sized block whose pixels entered the most containers: as a GL region (x, y, w, h from the
    bottom left) and as array slices (rows from the top)."""
    w, h = CROP
    entered = cost[..., 2].astype(np.float64)
    box = np.cumsum(np.cumsum(np.pad(entered, ((1, 0), (1, 0))), 0), 1)
    sums = box[h:, w:] - box[:-h, w:] - box[h:, :-w] + box[:-h, :-w]
    top, left = np.unravel_index(np.argmax(sums), sums.shape)
    H = cost.shape[0]
    return (int(left), int(H - top - h), w, h), (slice(top, top + h), slice(left, left + w))


@needs_data
@pytest.mark.parametrize("name", GROOMS)
def test_exact_and_fast_against_brute_force_on_the_densest_crop(grooms, frames, name):
    p, scene, cam = grooms[name]
    r, whole = frames[name]
    assert whole.unfinished == 0
    region, (rows, cols) = densest_crop(whole.cost)
    entered = whole.cost[rows, cols, 2]
    # the crop is where the walk works hardest: several containers per pixel on average
    assert entered.mean() > 1.5, (name, entered.mean())
    got = {}
    for mode in ("brute", "exact", "fast"):
        f = r.render(p, cam, SIZE, outputs=("ids", "geom"), mode=mode, region=region)
        assert f.unfinished == 0, (name, mode)
        got[mode] = (f.ids[rows, cols], f.geom[rows, cols, 3])
    brute_ids, brute_t = got["brute"]
    assert (brute_ids[..., 0] > 0).mean() > 0.5, name            # the crop shows hair, not background
    exact_ids, _ = got["exact"]
    differ = np.any(exact_ids != brute_ids, -1)
    assert not differ.any(), f"{name}: {int(differ.sum())} px of exact differ from brute in {region}"
    np.testing.assert_array_equal(exact_ids, whole.ids[rows, cols])    # a region renders as the frame
    # fast stops at the first container with a hit: the same pixels hit, and where it names another
    # fiber, that fiber lies no nearer than brute force's
    fast_ids, fast_t = got["fast"]
    np.testing.assert_array_equal(fast_ids[..., 0] > 0, brute_ids[..., 0] > 0)
    other = np.any(fast_ids != brute_ids, -1)
    assert np.all(fast_t[other] >= brute_t[other] * (1.0 - 1e-6)), name


def rays_meeting(scene, ro: np.ndarray, rd: np.ndarray) -> list[np.ndarray]:
    """Per ray, every container whose bounding cylinder (segment_cylinders) the ray passes, with the
    cylinder grown by a quarter of its radius all round: all containers tested in numpy, no hierarchy."""
    a, ez, length, radius = segment_cylinders(scene.segments)
    grow = 1.25 * radius
    a = a - ez * (grow - radius)[:, None] + scene.origin
    length = length + 2.0 * (grow - radius)
    out = []
    for o, d in zip(ro, rd):
        w = o - a
        wz, dz = (w * ez).sum(1), ez @ d
        wp, dp = w - wz[:, None] * ez, d[None] - dz[:, None] * ez
        # |wp + t dp| <= grow: a quadratic in t; then the height wz + t dz within [0, length]
        qa, qb, qc = (dp * dp).sum(1), (wp * dp).sum(1), (wp * wp).sum(1) - grow ** 2
        disc = qb * qb - qa * qc
        root = np.sqrt(np.maximum(disc, 0.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            t0 = np.where(qa > 0, (-qb - root) / qa, np.where(qc <= 0, -np.inf, np.inf))
            t1 = np.where(qa > 0, (-qb + root) / qa, np.where(qc <= 0, np.inf, -np.inf))
            z0, z1 = (0.0 - wz) / dz, (length - wz) / dz
        zlo = np.where(dz != 0, np.minimum(z0, z1), np.where((wz >= 0) & (wz <= length), -np.inf, np.inf))
        zhi = np.where(dz != 0, np.maximum(z0, z1), np.where((wz >= 0) & (wz <= length), np.inf, -np.inf))
        enter, leave = np.maximum(t0, zlo), np.minimum(t1, zhi)
        out.append(np.nonzero((disc >= 0) & (enter <= leave) & (leave >= 0.0))[0])
    return out


@needs_data
@pytest.mark.parametrize("name", GROOMS)
def test_walk_winner_is_the_float64_nearest_over_all_containers(grooms, frames, name):
    """Random rays of the frame, covered and not: the segment and fiber the walk keeps are those of the
    float64 brute force over every container whose bound the ray passes (found by testing them all)."""
    p, scene, cam = grooms[name]
    _, whole = frames[name]
    rng = np.random.default_rng(12)
    hit = whole.ids[..., 0] > 0
    ys, xs = np.nonzero(hit)
    pick = rng.choice(len(ys), 40, replace=False)
    # background rays from the hair's bounding rectangle on screen: they must miss as well
    y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
    by, bx = rng.integers(y0, y1, 200), rng.integers(x0, x1, 200)
    empty = ~hit[by, bx]
    py = np.concatenate([ys[pick], by[empty][:12]])
    px = np.concatenate([xs[pick], bx[empty][:12]])
    ro, rd = cam.rays(*SIZE)
    flat = py * SIZE[0] + px
    ro, rd = ro[flat], rd[flat]
    candidates = rays_meeting(scene, ro, rd)
    assert max(len(c) for c in candidates) > 2, name       # rays that pass several containers
    gpu = whole.ids[py, px]
    mismatch = []
    for k, cand in enumerate(candidates):
        sub = SimpleNamespace(origin=scene.origin, segments=scene.segments[cand])
        ref = reference.brute_nearest(sub, p, ro[k:k + 1], rd[k:k + 1], t_near=cam.near)
        want = (0, 0, 0, 0) if not ref.hit[0] else (ref.guide[0] + 1, ref.ring[0], ref.fiber[0],
                                                      cand[ref.segment[0]])
        if tuple(int(v) for v in gpu[k]) != tuple(int(v) for v in want):
            t_gpu = whole.geom[py[k], px[k], 3]
            mismatch.append((int(py[k]), int(px[k]), tuple(gpu[k]), want, float(t_gpu), float(ref.t[0])))
    assert not mismatch, f"{name}: {len(mismatch)} of {len(candidates)} rays differ: {mismatch[:4]}"


@pytest.mark.parametrize("n", [126, 128])
def test_every_fiber_the_float64_reference_sees_is_drawn(renderer, n):
    """128 containers fill a complete tree (no empty node at the coverage level), 126 leave one empty; the
    coverage pass must mark every pixel a container can cover in both (found on the grooms work, where
    every real groom has empty nodes and so hid this)."""
    from app.bench.suites import overlapping_scene

    p, scene, cam = overlapping_scene(n, 360)
    p = p.replace(**{"quality.visibility": "walk"})
    renderer.set_scene(scene)
    size = (160, 90)
    f = renderer.render(p, cam, size, outputs=("ids",), mode="exact")
    assert f.unfinished == 0
    ro, rd = cam.rays(*size)
    pick = np.random.default_rng(n).choice(len(ro), 300, replace=False)
    ref = reference.brute_nearest(scene, p, ro[pick], rd[pick], t_near=cam.near)
    gpu = f.ids.reshape(-1, 4)[pick]
    want = np.where(ref.hit[:, None], np.stack([ref.guide + 1, ref.ring, ref.fiber, ref.segment], 1), 0)
    assert ref.hit.sum() > 30
    differ = np.any(gpu != want, 1)
    missed = int((ref.hit & (gpu[:, 0] == 0)).sum())
    assert not differ.any(), f"{int(differ.sum())} of 300 rays differ ({missed} missed)"


def test_a_frame_does_not_depend_on_the_sizes_drawn_before(renderer, ctx):
    """The viewer draws interactive frames smaller than final ones and the benchmarks keep one renderer per
    scene on one context: a frame must be the same whatever was drawn before it."""
    from app.bench.suites import overlapping_scene
    from app.render.renderer import Renderer

    p, scene, cam = overlapping_scene(10, 360)
    p = p.replace(**{"quality.visibility": "walk"})
    renderer.set_scene(scene)
    big, small = (160, 90), (64, 36)
    fresh = renderer.render(p, cam, big, outputs=("ids",), mode="exact")
    assert fresh.hit.mean() > 0.05
    renderer.render(p, cam, small, outputs=("ids",), mode="exact")
    np.testing.assert_array_equal(renderer.render(p, cam, big, outputs=("ids",), mode="exact").ids, fresh.ids)
    other = Renderer(ctx)
    other.set_scene(scene)
    other.render(p, cam, small, outputs=("ids",), mode="exact")
    renderer.render(p, cam, big, outputs=("ids",), mode="exact")
    other.render(p, cam, small, outputs=("ids",), mode="exact")
    np.testing.assert_array_equal(renderer.render(p, cam, big, outputs=("ids",), mode="exact").ids, fresh.ids)
    other.release_targets()


def test_a_region_draws_only_its_rectangle(renderer):
    """``region=`` (tiled refinement) on a fresh renderer: pixels outside it stay background, inside it
    equal the whole frame's."""
    from app.bench.suites import overlapping_scene

    p, scene, cam = overlapping_scene(10, 360)
    p = p.replace(**{"quality.visibility": "walk"})
    renderer.set_scene(scene)
    size = (160, 90)
    whole = renderer.render(p, cam, size, outputs=("ids",), mode="exact")
    renderer.release_targets()
    part = renderer.render(p, cam, size, outputs=("ids",), mode="exact", region=(0, 0, 80, 45))
    inside = (slice(45, 90), slice(0, 80))          # GL's bottom-left quarter, rows from the top
    np.testing.assert_array_equal(part.ids[inside], whole.ids[inside])
    outside = part.hit.copy()
    outside[inside] = False
    assert whole.hit.sum() - whole.hit[inside].sum() > 0 and not outside.any()
