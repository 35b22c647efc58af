"""The highlights report (app/bench/highlights.py): its joint metric on synthetic pictures with known answers,
the tangent step of the two blends on a known joint, and a tiny run that writes every output."""

from __future__ import annotations

import csv
import math

import numpy as np

from app.bench import highlights as hl
from app.scene.containers import container_rows


def _strip(lum_left, lum_right, width=12):
    """One guide's pixels across a vertical joint at column 6: segment 0 left, segment 1 right."""
    color = np.zeros((4, width, 3))
    color[:, :6] = np.asarray(lum_left, float)[None, :, None]
    color[:, 6:] = np.asarray(lum_right, float)[None, :, None]
    ids = np.zeros((4, width, 4), np.uint32)
    ids[..., 0] = 1
    ids[:, 6:, 3] = 1
    return color, ids


def test_a_step_at_the_joint_counts_a_gradient_through_it_does_not():
    step = _strip([100] * 6, [130] * 6)
    pct, n = hl.joint_excess(*step)
    assert n == 4 and pct == 100.0                  # 30 levels where its neighbours step 0
    ramp = _strip(np.arange(6) * 10.0, 60.0 + np.arange(6) * 10.0)
    assert hl.joint_excess(*ramp)[0] == 0.0          # 10 a pixel on both sides, 10 across the joint
    small = _strip([100] * 6, [108] * 6)
    assert hl.joint_excess(*small)[0] == 0.0          # "more than 8 levels"


def test_pairs_of_one_fiber_and_of_two_are_told_apart():
    """Rows 0-1 show fiber 0 on both sides of the joint, rows 2-3 fiber 0 left and fiber 1 right (a fiber edge
    on the joint: the boundary between segments runs along fiber edges where fibers cross the joint plane
    at different heights); only the edge steps."""
    color, ids = _strip([100] * 6, [100] * 6)
    color[2:, 6:] = 140.0
    ids[2:, 6:, 2] = 1
    assert hl.joint_excess(color, ids) == (50.0, 4)
    assert hl.joint_excess(color, ids, same_fiber=True) == (0.0, 2)
    assert hl.joint_excess(color, ids, same_fiber=False) == (100.0, 2)
    ids[2:, 6:, 2] = 0
    ids[2:, 6:, 1] = 1                               # another ring is another fiber too
    assert hl.joint_excess(color, ids, same_fiber=False) == (100.0, 2)


def test_joint_bends_of_a_known_guide():
    th = math.radians(40.0)
    guide = np.array([[[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [math.sin(th), 0.0, 1.0 + math.cos(th)]]])
    rows = container_rows(guide, np.array([0.45]), 0.0, np.zeros(3))
    assert np.allclose(hl.joint_bends(rows), [40.0], atol=1e-3)


def test_other_guides_and_background_are_no_joint():
    color, ids = _strip([100] * 6, [200] * 6)
    ids[:, 6:, 0] = 2                                # another guide to the right: no joint of one guide
    pct, n = hl.joint_excess(color, ids)
    assert n == 0 and math.isnan(pct)
    ids[:, 6:, 0] = 0                                # background
    assert hl.joint_excess(color, ids)[1] == 0


def test_tangent_steps_of_a_known_bend():
    """A 40-degree joint on a container half as wide as its segments are long: the height blend steps by
    degrees at the wall, the plane blend not at all."""
    th = math.radians(40.0)
    guide = np.array([[[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [math.sin(th), 0.0, 1.0 + math.cos(th)]]])
    rows = container_rows(guide, np.array([0.45]), 0.0, np.zeros(3))
    old = hl.joint_tangent_steps(rows, hl.height_blended_axis)
    new = hl.joint_tangent_steps(rows, hl.joint_blended_axis)
    assert old.shape == (1,) and 3.0 < old[0] < 20.0
    assert new[0] < 1e-4
    straight = container_rows(np.array([[[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 2.0]]]), np.array([0.45]),
                              0.0, np.zeros(3))
    assert hl.joint_tangent_steps(straight, hl.height_blended_axis)[0] < 1e-4


def test_tiny_run_writes_every_output(tmp_path):
    pictures = tmp_path / "pictures"
    for label in ("before", "after"):
        rows = hl.run(size=(48, 27), label=label, out=tmp_path, scenes=("bent strand",), pictures_dir=pictures)
        assert [r["method"] for r in rows] == ["virtual", "explicit"]
        for r in rows:
            assert r["joint_pairs"] >= 0 and r["tangent_step_plane_max_deg"] < 1e-3
            assert 0 <= r["joint_pairs_one_fiber"] <= r["joint_pairs"] and r["bend_p50_deg"] > 30.0
    with open(tmp_path / "highlights.csv") as f:
        assert {r["label"] for r in csv.DictReader(f)} == {"before", "after"}
    assert (tmp_path / "contact_sheet.png").stat().st_size > 0
    assert "contact_sheet.png" in (tmp_path / "README.md").read_text()


def test_a_csv_from_before_the_newer_columns_is_kept(tmp_path):
    """The other label's rows may come from a run that had fewer columns: they stay, and the table leaves
    their new cells empty instead of failing."""
    old = [c for c in hl.COLUMNS if c not in ("joint_pairs_one_fiber", "joint_excess_one_fiber_pct",
                                              "bend_p50_deg", "bend_p90_deg")]
    with open(tmp_path / "highlights.csv", "w", newline="") as f:
        w = csv.DictWriter(f, old)
        w.writeheader()
        w.writerow({c: ("before" if c == "label" else "bent strand" if c == "scene" else
                        "virtual" if c == "method" else "1.5") for c in old})
    hl.run(size=(48, 27), label="after", out=tmp_path, scenes=("bent strand",), pictures_dir=tmp_path / "p")
    with open(tmp_path / "highlights.csv") as f:
        labels = [r["label"] for r in csv.DictReader(f)]
    assert labels.count("before") == 1 and labels.count("after") == 2
    assert "| before | bent strand | virtual |" in (tmp_path / "README.md").read_text()
