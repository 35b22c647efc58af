"""The looks suite (issue 15): its metrics on pictures whose answer is known, the child-strand generator,
and one tiny run against a shared groom."""

from __future__ import annotations

import math

import numpy as np
import pytest

from app.bench import looks, strand_reference
from app.bench.looks import angle_difference_deg, coverage_iou, orientation_agreement, orientation_field


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
    w = lambda k, tt: (rows[k, 3] + tt * (rows[k, 7] - rows[k, 3]))[..., None]   # noqa: E731
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
    p = lambda k, tt: rows[k, 0:3] + tt[..., None] * axis[k] + w(k, tt) * d[k]   # noqa: E731
    for k in range(7):
        assert np.allclose(p(k, t1[k]), p(k + 1, t0[k + 1]), atol=2e-3 * R + 2e-3 * 0.4)
    # the offset from the strand at its tip is (1 - taper) R at most
    tip = np.linalg.norm(p(7, t1[7]) - strands[np.asarray(rows[7, 19], int), -1], axis=-1)
    assert tip.max() <= (1.0 - taper) * R * (1 + 1e-2) + 1e-3 and tip.max() >= 0.8 * (1.0 - taper) * R


# --- a tiny run on a shared groom ---------------------------------------------------------------------------
def test_suite_smoke_on_one_groom(ctx, tmp_path):
    from app.bench.grooms import HAIR_DATA
    from app.bench.suites import SUITES, Env

    if not (HAIR_DATA / "Curly_100.ply").exists():
        pytest.skip(f"{HAIR_DATA}: shared hair data not found")

    cfg = SUITES["looks"].configs("smoke")[0]
    env = Env(ctx, reps=1, warmup=0, level="smoke", out=str(tmp_path))
    rows = SUITES["looks"].run(env, cfg)
    assert [r["variant"] for r in rows] == ["before"]
    r = rows[0]
    assert 0.0 < r["iou"] <= 1.0 and 0.0 < r["covered_reference"] and 0.0 < r["covered_virtual"]
    assert r["virtual_fibers"] == 360_000 and r["capped"] == "yes"
    assert r["reference_fibers"] == r["reference_strands"] * r["children"]
    assert r["reference_segments"] * r["reference_fibers"] <= cfg["max_instances"]
    sheet = tmp_path / "sheet_Curly_100.png"
    from app.contact_sheet import labels_of, layout_of

    labels = labels_of(sheet)
    assert len(labels) == 2 and labels[0].startswith("Curly_100.ply reference") and labels[1].startswith("before")
    boxes, _ = layout_of(sheet)
    assert boxes[0][1] == boxes[1][1]                                         # one row: reference | before


def test_set_fibers_refuses_records_that_do_not_fit_the_rows(ctx):
    from app.render.explicit import ExplicitRenderer
    from app.scene.grooms import container_rows
    from app.scene.containers import Scene

    strands = np.stack([np.stack([np.zeros(3), np.zeros(3), np.linspace(0, 1, 3)], -1)])
    scene = Scene(container_rows(strands, np.full(1, 0.1), 0.0, np.zeros(3)), np.zeros(3), "one", 1)
    records = strand_reference.child_records(scene.segments, strand_reference.child_offsets(1, 4))
    e = ExplicitRenderer(ctx)
    with pytest.raises(ValueError, match="records"):
        e.set_fibers(scene, records[:-1], 4, 0.01)
    assert e.set_fibers(scene, records, 4, 0.01).fibers == 4
    e.release()
