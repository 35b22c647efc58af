"""The looks suite (issue 15): its metrics on pictures whose answer is known, the child-strand generator,
and one tiny run against a shared groom."""

from __future__ import annotations

import math

import numpy as np
import pytest

from app.bench import looks, strand_reference
from app.bench.looks import (
    angle_difference_deg,
    coverage_iou,
    orientation_agreement,
    orientation_field,
)


def stripes(angle_deg: float, size=(128, 128), period: float = 6.0) -> np.ndarray:
    """Grey stripes that run along ``angle_deg`` (from +x toward +y, rows downward), as uint8 RGB."""
    h, w = size
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    a = math.radians(angle_deg)
    across = -math.sin(a) * x + math.cos(a) * y        # constant along (cos a, sin a)
    g = 0.5 + 0.5 * np.cos(2 * np.pi * across / period)
    return np.repeat((g * 255).round().astype(np.uint8)[..., None], 3, -1)


def disc(size, centre, radius) -> np.ndarray:
    y, x = np.mgrid[0:size[0], 0:size[1]]
    return (x - centre[0]) ** 2 + (y - centre[1]) ** 2 <= radius ** 2


# --- coverage -----------------------------------------------------------------------------------------
def test_iou_identical_is_one_and_disjoint_is_zero():
    a = disc((96, 128), (40, 48), 20)
    assert coverage_iou(a, a) == 1.0
    b = disc((96, 128), (100, 48), 15)
    assert coverage_iou(a, b) == 0.0
    assert coverage_iou(np.zeros((8, 8), bool), np.zeros((8, 8), bool)) == 1.0


def test_iou_of_overlapping_squares_is_the_area_ratio_and_the_blur_fills_fine_gaps():
    a = np.zeros((100, 100), bool)
    b = np.zeros((100, 100), bool)
    a[20:60, 20:60] = True
    b[20:60, 40:80] = True                               # half overlaps: IoU 800 / 2400 = 1/3
    assert coverage_iou(a, b) == pytest.approx(1 / 3, abs=0.01)
    # hair-like coverage: two columns of three lit reads as covered after the 2 px blur (half is the
    # threshold); without the blur only the lit pixels count
    comb = a.copy()
    comb[:, ::3] = False
    assert coverage_iou(a, comb) > 0.9
    assert coverage_iou(a, comb, blur_px=0.0) < 0.7
    sparse = a.copy()
    sparse[:, ::3] = sparse[:, 1::3] = False                 # one column of three: below half, uncovered
    assert coverage_iou(a, sparse) < 0.1
    with pytest.raises(ValueError):
        coverage_iou(a, a[:50])


# --- orientation ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("angle", [0.0, 30.0, 45.0, 90.0, 125.0])
def test_orientation_field_finds_the_stripes_direction(angle):
    d, c = orientation_field(looks.luminance(stripes(angle)))
    inner = (slice(24, -24), slice(24, -24))
    err = angle_difference_deg(d[inner], math.radians(angle))
    assert np.median(err) < 1.0
    assert np.median(c[inner]) > 0.9


def test_orientation_agreement_identical_rotated_and_unoriented():
    mask = np.ones((128, 128), bool)
    same, frac = orientation_agreement(stripes(20), mask, stripes(20), mask)
    assert same == pytest.approx(0.0, abs=0.5) and frac > 0.9
    turned, _ = orientation_agreement(stripes(20), mask, stripes(55), mask)
    assert turned == pytest.approx(35.0, abs=1.5)
    across, _ = orientation_agreement(stripes(170), mask, stripes(10), mask)   # mod 180: 20, not 160
    assert across == pytest.approx(20.0, abs=1.5)
    flat = np.full((128, 128, 3), 128, np.uint8)                               # nothing oriented: no answer
    none, frac = orientation_agreement(flat, mask, stripes(0), mask)
    assert math.isnan(none) and frac == 0.0
    apart, frac = orientation_agreement(stripes(0), disc((128, 128), (30, 64), 20),
                                        stripes(0), disc((128, 128), (100, 64), 20))
    assert math.isnan(apart) and frac == 0.0


# --- child strands ----------------------------------------------------------------------------------------
def test_disc_reference_stays_reachable_and_the_full_level_shows_both():
    assert [c["references"] for c in looks.configs("full")] == [("interpolated", "disc")] * len(looks.GROOMS)
    rows = [{"groom": "g", "variant": "before", "reference": m, "iou": 0.5, "orientation_deg": 20.0}
            for m in ("interpolated", "disc")]
    assert len(looks.targets(rows)) == 2                  # the disc rows are shown, not judged


def test_child_offsets_count_bounds_and_seed():
    o = strand_reference.child_offsets(50, 200, seed=3)
    assert o.shape == (50, 200, 2)
    r = np.linalg.norm(o, axis=-1)
    assert r.max() <= 1.0 and np.all(r[:, 0] == 0.0)      # child 0 is the strand itself
    assert 0.6 < np.mean(r[:, 1:]) < 0.73                   # uniform by area: mean radius 2/3
    assert np.array_equal(o, strand_reference.child_offsets(50, 200, seed=3))
    assert not np.array_equal(o, strand_reference.child_offsets(50, 200, seed=4))
    with pytest.raises(ValueError):
        strand_reference.child_offsets(5, 0)


@pytest.mark.parametrize("taper", [0.0, 0.8])
def test_children_follow_their_strand_at_a_bounded_constant_offset(taper):
    from app.scene.grooms import container_rows

    t = np.linspace(0.0, 1.0, 9)
    strands = np.stack([np.stack([np.cos(3 * t) + k, np.sin(3 * t), 2 * t], -1) for k in range(3)])
    R = 0.1
    rows = container_rows(strands, np.full(3, R), taper, np.zeros(3))
    w = lambda k, tt: (rows[k, 3] + tt * (rows[k, 7] - rows[k, 3]))[..., None]
    offsets = strand_reference.child_offsets(3, 16, seed=1)
    rec = strand_reference.child_records(rows, offsets).reshape(len(rows), 16, 6)
    half = rec[..., :5].copy().view(np.float16).astype(np.float64)
    d, t0, t1 = half[..., 0:3], half[..., 3], half[..., 4]
    assert np.all(np.linalg.norm(d, axis=-1) <= 1.0 + 1e-3)
    axis = rows[:, 4:7] - rows[:, 0:3]
    unit = axis / np.linalg.norm(axis, axis=1, keepdims=True)
    assert np.all(np.abs(np.einsum("rcx,rx->rc", d, unit)) < 2e-3)           # in the normal plane
    assert np.all(t1 >= t0)
    # along each strand the unit offset is the same child's: |d| does not change from piece to piece
    per_strand = np.linalg.norm(d, axis=-1).reshape(3, 8, 16)
    assert np.allclose(per_strand, per_strand[:, :1], atol=2e-3)
    # a child's end on one piece is its start on the next: no gap at a joint
    p = lambda k, tt: rows[k, 0:3] + tt[..., None] * axis[k] + w(k, tt) * d[k]
    for k in range(7):
        assert np.allclose(p(k, t1[k]), p(k + 1, t0[k + 1]), atol=2e-3 * R + 2e-3 * 0.4)
    # the offset from the strand at its tip is (1 - taper) R at most
    tip = np.linalg.norm(p(7, t1[7]) - strands[np.asarray(rows[7, 19], int), -1], axis=-1)
    assert tip.max() <= (1.0 - taper) * R * (1 + 1e-2) + 1e-3 and tip.max() >= 0.8 * (1.0 - taper) * R


# --- interpolated children ---------------------------------------------------------------------------------
def wavy_guides(n=12, points=9, seed=0):
    """n guides on a 4 x 3 grid of roots 1 apart, each a different wavy, leaning strand of 2 .. 3 long."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, points)
    out = []
    for i in range(n):
        root = np.array([i % 4, i // 4, 0.0])
        a, b, L = rng.uniform(-0.5, 0.5), rng.uniform(0, 2 * np.pi), rng.uniform(2, 3)
        shape = np.stack([a * t + 0.2 * np.sin(6 * t + b), 0.2 * np.cos(5 * t + b), L * t], -1)
        out.append(root + shape - shape[0])
    return np.stack(out)


def test_interpolation_is_deterministic_with_a_seed():
    g = strand_reference.resample_guides(wavy_guides(), 16)
    r1, p1 = strand_reference.child_roots(g, 500, seed=7)
    r2, p2 = strand_reference.child_roots(g, 500, seed=7)
    r3, _ = strand_reference.child_roots(g, 500, seed=8)
    assert np.array_equal(r1, r2) and np.array_equal(p1, p2) and not np.array_equal(r1, r3)
    a = strand_reference.interpolate(g, r1, 8, parents=p1)
    assert np.array_equal(a, strand_reference.interpolate(g, r2, 8, parents=p2))
    assert a.shape == (500, 9, 3) and np.isfinite(a).all()


def test_child_roots_counts_parents_and_spread():
    g = strand_reference.resample_guides(wavy_guides(), 16)
    roots, parents = strand_reference.child_roots(g, 12 + 12 * 40, seed=1)
    assert roots.shape == (492, 3)
    assert np.array_equal(roots[:12], g[:, 0]) and np.array_equal(parents[:12], np.arange(12))
    assert np.array_equal(np.bincount(parents), np.full(12, 41))        # every guide the same number
    off = roots[12:] - g[parents[12:], 0]
    dist = np.linalg.norm(off, axis=1)
    assert dist.max() <= 1.0 + 1e-9 and dist.mean() > 0.6               # spacing 1: uniform by area, mean 2/3
    first = g[:, 1] - g[:, 0]
    first /= np.linalg.norm(first, axis=1, keepdims=True)
    assert np.abs(np.einsum("nx,nx->n", off, first[parents[12:]])).max() < 1e-9   # in the normal plane
    with pytest.raises(ValueError):
        strand_reference.child_roots(g, 5)


def test_a_child_rooted_at_a_guide_root_is_that_guide():
    g = strand_reference.resample_guides(wavy_guides(), 16)
    for clump in (0.0, 0.25, 1.0):
        kids = strand_reference.interpolate(g, g[:, 0], 16, clump=clump)
        assert np.allclose(kids, g, atol=1e-9)
    # on the guides' own 8-piece resampling as well (the common parameter is finer than what is drawn)
    fine = strand_reference.resample_guides(wavy_guides(), 64)
    kids = strand_reference.interpolate(fine, fine[:, 0], 8)
    assert np.allclose(kids, strand_reference.resample_guides(wavy_guides(), 8), atol=1e-9)


def test_with_one_guide_blended_a_child_is_its_nearest_guide_translated():
    """k = 1 (the looks-why comparison): the child copies the shape of the guide nearest its root, moved to
    its root, so it curls as much as that guide whatever its neighbours do."""
    g = strand_reference.resample_guides(wavy_guides(), 16)
    rng = np.random.default_rng(4)
    roots = g[:, 0][rng.integers(0, len(g), 40)] + np.c_[rng.uniform(-0.45, 0.45, (40, 2)), np.zeros(40)]
    kids = strand_reference.interpolate(g, roots, 16, k=1, clump=0.0)
    nearest = np.argmin(np.linalg.norm(roots[:, None] - g[None, :, 0], axis=2), axis=1)
    assert np.allclose(kids - roots[:, None], g[nearest] - g[nearest, :1], atol=1e-9)


def test_children_of_two_parallel_straight_guides_lie_between_them():
    t = np.linspace(0.0, 1.0, 5)[:, None]
    g = np.stack([np.array([0.0, 0, 0]) + t * [0.3, 0, 2], np.array([1.0, 0, 0]) + t * [0.3, 0, 2]])
    g = strand_reference.resample_guides(g, 32)
    x = np.linspace(0.0, 1.0, 21)
    roots = np.stack([x, np.zeros_like(x), np.zeros_like(x)], -1)
    for clump in (0.0, 0.25):
        kids = strand_reference.interpolate(g, roots, 10, clump=clump)
        if clump == 0.0:        # both guides have one shape: each child is its root plus that shape
            s = np.linspace(0.0, 1.0, 11)[:, None]
            assert np.allclose(kids - roots[:, None], (s * [0.3, 0.0, 2.0])[None], atol=1e-9)
        u = kids[..., 0] - 0.3 * kids[..., 2] / 2.0                    # x at the guides' lean removed
        assert np.all(u >= -1e-9) and np.all(u <= 1.0 + 1e-9)           # between the two guides
        assert np.allclose(kids[..., 1], 0.0) and np.allclose(kids[:, -1, 2], 2.0)
    # the clump pulls a child toward its nearer guide at the tip, not past it
    kids = strand_reference.interpolate(g, roots, 10, clump=0.5)
    tip_u = kids[:, -1, 0] - 0.3
    near = np.round(x)
    moved = np.abs(tip_u - near) < np.abs(x - near) - 1e-6
    assert np.all(np.abs(tip_u - near) <= np.abs(x - near) + 1e-9) and moved[(x > 0) & (x < 1) & (x != 0.5)].all()


def test_shorter_children_follow_the_blend_and_tips_taper():
    g = strand_reference.resample_guides(wavy_guides(), 64)
    roots = g[:, 0]
    full = strand_reference.interpolate(g, roots, 8, clump=0.0)
    half = strand_reference.interpolate(g, roots, 8, clump=0.0, lengths=np.full(12, 0.5))
    assert np.allclose(half[:, -1], full[:, 4], atol=1e-9)              # half the length: the middle
    from app.scene.grooms import container_rows

    rows = container_rows(full, np.full(12, 0.1), 1.0 - 0.2, np.zeros(3))
    assert np.allclose(rows.reshape(12, 8, 20)[:, -1, 7], 0.02)         # tip width 0.2 of the root's


@pytest.mark.parametrize("radius", [0.05, 2.0])       # 2.0: pieces of 0.02 .. 0.2 radii, as Curly's coils
def test_axial_records_run_exactly_from_joint_to_joint(radius):
    from app.scene.grooms import container_rows

    g = strand_reference.resample_guides(wavy_guides(), 8)
    rows = container_rows(g, np.full(12, radius), 0.8, np.zeros(3))
    depth = np.linspace(0.0, 1.0, 12)
    rec = strand_reference.axial_records(rows, depth)
    half = rec[:, :5].copy().view(np.float16).astype(np.float64)
    d, t0, t1 = half[:, 0:3], half[:, 3], half[:, 4]
    assert np.allclose(np.linalg.norm(d, axis=1), depth[rows[:, 19].astype(int)], atol=2e-3)
    w = lambda tt: rows[:, 3] + tt * (rows[:, 7] - rows[:, 3])
    P = lambda tt: rows[:, 0:3] + tt[:, None] * (rows[:, 4:7] - rows[:, 0:3]) + w(tt)[:, None] * d
    h = np.linalg.norm(rows[:, 4:7] - rows[:, 0:3], axis=1)[:, None]
    tol = 2e-3 * max(h.max(), radius)
    assert np.allclose(P(t0), rows[:, 0:3], atol=tol) and np.allclose(P(t1), rows[:, 4:7], atol=tol)


def test_degenerate_strands_give_no_nan():
    t = np.linspace(0.0, 1.0, 6)[:, None]
    strands = [np.zeros((6, 3)),                                         # zero length
               np.array([[1.0, 0, 0]] * 3 + [[1.0, 0, 1.0]] * 3),         # duplicate points
               np.array([[2.0, 0, 0], [2.0, 0, 1e-7]]),                    # a stub
               np.array([1.0, 0, 0]) + t * [0, 0, 1.0],                    # the same root as the second
               np.array([[3.0, 0, 0]])]                                    # one point
    g = strand_reference.resample_guides(strands, 8)
    assert g.shape == (5, 9, 3) and np.isfinite(g).all()
    assert np.allclose(g[0], 0.0) and np.allclose(g[4], [3.0, 0, 0])
    roots, parents = strand_reference.child_roots(g, 205, seed=2)
    assert np.isfinite(roots).all()
    kids = strand_reference.interpolate(g, roots, 8, parents=parents,
                                        lengths=np.random.default_rng(0).random(205))
    assert np.isfinite(kids).all()
    assert np.isfinite(strand_reference.interpolate(g[:1], roots[:3], 4)).all()   # one zero-length guide
    assert np.isfinite(strand_reference.root_spacing(np.zeros((4, 3)))).all()
    with pytest.raises(ValueError):
        strand_reference.resample_guides([np.zeros((0, 3))], 4)


# --- a tiny run on a shared groom ---------------------------------------------------------------------------
def test_suite_smoke_on_one_groom(ctx, tmp_path):
    from app.bench import looks
    from app.bench.grooms import HAIR_DATA
    from app.bench.suites import SUITES, Env

    if not (HAIR_DATA / "Curly_100.ply").exists():
        pytest.skip(f"{HAIR_DATA}: shared hair data not found")

    cfg = SUITES["looks"].configs("smoke")[0]
    env = Env(ctx, reps=1, warmup=0, level="smoke", out=str(tmp_path))
    rows = SUITES["looks"].run(env, cfg)
    r0_fibers = rows[0]["virtual_fibers"]
    assert [(r["variant"], r["reference"]) for r in rows] == [(v, "interpolated") for v in looks.VARIANTS]
    assert rows[2]["sets"] == " ".join(looks.VARIANTS["after"]) and rows[2]["iou"] != rows[0]["iou"]
    # every picture is also held to the file's strands alone: a finite angle, and not the same for all
    assert all(0.0 <= r["strands_deg"] <= 90.0 and 0.0 <= r["reference_strands_deg"] <= 90.0 for r in rows)
    assert len({r["strands_deg"] for r in rows}) > 1
    # each variant counts its own fibers: groom_auto draws far fewer than the defaults the reference matches
    assert rows[0]["variant_fibers"] == r0_fibers and rows[1]["variant_fibers"] < r0_fibers
    r = rows[0]
    assert 0.0 < r["iou"] <= 1.0 and 0.0 < r["covered_reference"] and 0.0 < r["covered_virtual"]
    assert r["virtual_fibers"] == 360_000 and r["capped"] == "yes"
    # capped: as many fibers as the ribbon budget holds (none dropped on Curly), each widened
    assert r["reference_fibers"] == cfg["max_instances"] // r["reference_segments"] - r["reference_dropped"]
    assert r["reference_dropped"] == 0 and r["reference_fiber_radius"] > 0.01
    sheet = tmp_path / "sheet_Curly_100.png"
    from app.contact_sheet import labels_of, layout_of

    labels = labels_of(sheet)
    assert len(labels) == 5 and labels[0] == "Curly_100.ply: its 100 file strands alone"
    assert labels[1].startswith("Curly_100.ply reference (interpolated)")
    assert [x.split(":")[0] for x in labels[2:]] == list(looks.VARIANTS) and "off the strands" in labels[2]
    boxes, _ = layout_of(sheet)
    assert len({b[1] for b in boxes}) == 1                  # one row: strands | reference | before | auto | after


def test_strands_reference_is_the_file_strands_alone():
    from app.bench.grooms import HAIR_DATA
    from app.presets import resolve_params
    from app.scene.generators import build_scene
    from app.scene.grooms import load_groom, resample_many

    if not (HAIR_DATA / "Curly_100.ply").exists():
        pytest.skip(f"{HAIR_DATA}: shared hair data not found")
    p, _ = resolve_params(str(HAIR_DATA / "Curly_100.ply"), [])
    scene = build_scene(p)
    ref = strand_reference.build(p, scene, method="strands")
    assert ref.method == "strands" and ref.fibers == ref.strands == 100 and not ref.capped
    assert ref.fiber_radius == strand_reference.MAX_WIDENED_RADIUS and ref.tip_width == 1.0
    rows = ref.scene.segments.reshape(100, ref.n_segments, 20)
    groom = load_groom(p["scene.groom_file"], up=p["scene.groom_up"], scale=p["scene.groom_scale"])
    want = resample_many(groom.strands, ref.n_segments) - scene.origin
    assert np.allclose(rows[:, :, 0:3], want[:, :-1], atol=1e-3 * float(np.median(rows[:, 0, 3])))
    assert (rows[:, :, 3] == rows[:, :, 7]).all()                  # full width to the tip: no taper


def test_set_fibers_refuses_records_that_do_not_fit_the_rows(ctx):
    from app.render.explicit import ExplicitRenderer
    from app.scene.containers import Scene
    from app.scene.grooms import container_rows

    strands = np.stack([np.stack([np.zeros(3), np.zeros(3), np.linspace(0, 1, 3)], -1)])
    scene = Scene(container_rows(strands, np.full(1, 0.1), 0.0, np.zeros(3)), np.zeros(3), "one", 1)
    records = strand_reference.child_records(scene.segments, strand_reference.child_offsets(1, 4))
    e = ExplicitRenderer(ctx)
    with pytest.raises(ValueError, match="records"):
        e.set_fibers(scene, records[:-1], 4, 0.01)
    assert e.set_fibers(scene, records, 4, 0.01).fibers == 4
    e.release()
