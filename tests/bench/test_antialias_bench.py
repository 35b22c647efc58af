"""The antialias measuring stick (app/bench/antialias.py): its metrics on synthetic images with known answers,
the viewer's accumulation against the renderer's supersampling, and a tiny run that writes every output."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from app.bench import antialias as aa


def test_linear_round_trip_and_the_half_covered_pixel():
    levels = np.arange(256, dtype=np.float64)
    assert np.allclose(aa.to_srgb_levels(aa.to_linear(levels)), levels)
    assert aa.to_linear(0.0) == 0.0 and aa.to_linear(255.0) == 1.0
    # a pixel half covered by white on black: the box filter averages light, not levels
    half = aa.to_srgb_levels(aa.to_linear(np.array([0.0, 255.0])).mean())
    assert half == pytest.approx(255.0 * 0.5 ** (1 / 2.2))
    assert half > 180.0


def test_changed_share_counts_covered_pixels_past_the_threshold():
    a = np.full((10, 10, 3), 100.0)
    b = a.copy()
    covered = np.zeros((10, 10), bool)
    covered[:5] = True                      # 50 covered pixels
    b[0, :, 1] += 5.0                       # 10 covered pixels change by 5 in one channel: counted
    b[1, :, 2] -= 4.0                       # 10 change by exactly 4: "more than 4/255" leaves them out
    b[7, :, 0] += 50.0                      # uncovered: not counted
    assert aa.changed_share(a, b, covered) == pytest.approx(20.0)
    assert aa.changed_share(a, b, covered, threshold=3.0) == pytest.approx(40.0)
    assert aa.changed_share(a, a, covered) == 0.0
    assert math.isnan(aa.changed_share(a, b, np.zeros((10, 10), bool)))
    with pytest.raises(ValueError, match="shapes differ"):
        aa.changed_share(a, b[:5], covered)


def test_error_stats_mean_and_p99_of_the_largest_channel():
    ref = np.zeros((10, 10, 3))
    img = ref.copy()
    img[..., 1] = np.arange(100).reshape(10, 10)        # errors 0..99 in green
    img[..., 0] = np.arange(100).reshape(10, 10) / 2    # smaller in red: the largest channel counts
    covered = np.ones((10, 10), bool)
    mean, p99 = aa.error_stats(img, ref, covered)
    assert mean == pytest.approx(49.5)
    assert p99 == pytest.approx(98.01)
    covered[5:] = False                                 # only errors 0..49
    assert aa.error_stats(img, ref, covered)[0] == pytest.approx(24.5)
    assert aa.error_stats(img, img, covered) == (0.0, 0.0)
    assert all(math.isnan(v) for v in aa.error_stats(img, ref, np.zeros((10, 10), bool)))


def test_reference_offsets_are_stratified_jittered_and_repeatable():
    offs = np.array(aa.reference_offsets(16))
    assert offs.shape == (256, 2)
    assert (offs >= -0.5).all() and (offs < 0.5).all()
    cells = np.floor((offs + 0.5) * 16).astype(int)
    assert len({tuple(c) for c in cells}) == 256          # one ray in each of the 16 x 16 cells
    centres = (cells + 0.5) / 16 - 0.5
    assert np.abs(offs - centres).max() > 0.01            # jittered, not the cell centres
    assert np.array_equal(offs, np.array(aa.reference_offsets(16)))


def test_crop_and_best_mode():
    covered = np.zeros((30, 40), bool)
    covered[20:28, 30:38] = True
    y, x = aa._crop_box(covered, 10, 10)
    assert covered[y:y + 10, x:x + 10].sum() == covered.sum()
    rows = [{"mode": "none", "stability_changed_pct": 1.0, "error_mean_levels": 1.0},
            {"mode": "reference 16x16 (box)", "stability_changed_pct": 0.0, "error_mean_levels": 0.0},
            {"mode": "msaa 2", "stability_changed_pct": 50.0, "error_mean_levels": 1.0},
            {"mode": "supersample 3", "stability_changed_pct": 40.0, "error_mean_levels": 9.0}]
    assert aa.best_mode(rows) == "supersample 3"


def test_viewer_accumulation_is_the_walks_supersampling(ctx):
    """The viewer accumulates single-ray frames at its own (sorted) stratified offsets; the walk supersamples
    with the same offsets in another order, averaged the same way: the pictures must agree."""
    from app.gl.shaders import ProgramCache

    size = (48, 27)
    s = aa.load_subject(ctx, ProgramCache(), "fur-ball far", size)
    s.p = s.p.replace(**{"quality.visibility": "walk"})
    try:
        acc = np.round(aa.render_mode(s, "viewer accumulation 16", size))
        ss = aa.render_mode(s, "supersample 4", size)
        none = aa.render_mode(s, "none", size)
        assert np.abs(acc - ss).max() <= 1.0
        assert np.abs(acc - none).max() > 20.0       # and it is not the unfiltered frame
    finally:
        s.renderer.release_targets()


def test_the_move_is_in_pixels_and_pans_right(ctx):
    """The bench's camera move is the renderer's offset in pixel units: an offset of one whole pixel must give
    the same picture one column over (the content moves left as the camera pans right), so 0.1 is a tenth."""
    from app.gl.shaders import ProgramCache

    size = (64, 36)
    s = aa.load_subject(ctx, ProgramCache(), "default", size)
    try:
        a = aa.render_mode(s, "none", size)
        b = aa.render_mode(s, "none", size, (1.0, 0.0))
        assert np.abs(b - a).max() > 20.0
        assert np.array_equal(b[:, :-1], a[:, 1:])
        tenth = aa.render_mode(s, "none", size, (aa.MOVE_PX, 0.0))
        assert 0.0 < aa.changed_share(a, tenth, np.ones(size[::-1], bool)) < 100.0
    finally:
        s.renderer.release_targets()


def test_tiny_run_writes_every_output(tmp_path):
    every = aa.run(size=(32, 18), reps=1, scenes=("default", "fur-ball far"), ref_n=2, out=tmp_path, pairs=1,
                   medium_scenes=("fur-ball far",), dolly_spec=(0.5, 1.0, 3))
    rows = [r for r in every if r["scene"] == "default"]
    modes = [r["mode"] for r in rows]
    assert modes[0] == "none" and modes[-1] == "reference 2x2 (box)"
    assert {"supersample 4", "viewer accumulation 16"} <= set(modes)
    for r in rows:
        assert 0.0 <= r["stability_changed_pct"] <= 100.0
        assert r["error_mean_levels"] >= 0.0 and r["error_p99_levels"] >= 0.0
        assert r["cost_vs_none"] > 0.0 and r["covered_px"] > 0
    assert next(r for r in rows if r["mode"] == "none")["cost_vs_none"] == 1.0
    with open(tmp_path / "antialias.csv") as f:
        assert len(list(csv.DictReader(f))) == len(every)
    for name in ("README.md", "antialias.png", "contact_sheet.png", "dolly.png"):
        assert (tmp_path / name).stat().st_size > 0
    readme = (tmp_path / "README.md").read_text()
    assert "<= 10%" in readme and "## The medium against the scan" in readme and "## Dolly" in readme
    with open(tmp_path / "ab.csv") as f:
        ab = list(csv.DictReader(f))
    assert [a["scene"] for a in ab] == ["default", "fur-ball far"] and all(float(a["median"]) > 0 for a in ab)
    assert aa.DOLLY_SCENE == "default"
    with open(tmp_path / "medium.csv") as f:
        assert [m["variant"] for m in csv.DictReader(f)] == list(aa.BANDS)
    with open(tmp_path / "dolly.csv") as f:
        assert len(list(csv.DictReader(f))) == 3 * len(aa.BANDS)


def test_medium_band_reaches_the_shader_and_is_undone(ctx):
    """The bench's scan-alone and medium-alone variants: the band override changes the picture of a scene in
    the medium (sintel), and leaves the renderer's own defines as they were afterwards."""
    from app.gl.shaders import ProgramCache
    from app.render import renderer as rmod

    # 32x18: with fibers.groom_auto (on by default) sintel's fibers are fewer and wider, and at 64x36 a third
    # of its pixels still blend scan and medium
    size = (32, 18)
    s = aa.load_subject(ctx, ProgramCache(), "sintel_hair.tfx", size)
    defines = rmod.model_defines
    try:
        p = aa._mode_params(s, aa.FILTERED)
        pics = {}
        for k, band in aa.BANDS.items():
            with aa.medium_band(band):
                pics[k] = s.renderer.render(p, s.cam, size, outputs=("color",)).color.astype(np.int32)
        assert rmod.model_defines is defines
        assert np.abs(pics["scan only"] - pics["medium only"]).max() > 8
        assert np.array_equal(pics["filtered"], pics["medium only"]), "sintel's footprints are past the band"
    finally:
        s.renderer.release_targets()


def test_unknown_scene_says_what_is_allowed(ctx):
    from app.gl.shaders import ProgramCache

    with pytest.raises(ValueError, match="use one of default"):
        aa.load_subject(ctx, ProgramCache(), "teapot", (16, 9))


def test_explicit_scene_runs_its_own_modes(tmp_path):
    """An explicit scene: the explicit baseline's modes and the virtual frames of the same scene, all held
    against the explicit reference."""
    rows = aa.run(size=(32, 18), reps=1, scenes=("default (explicit)",), ref_n=2, out=tmp_path)
    assert [r["mode"] for r in rows] == list(aa.EXPLICIT_MODES) + ["reference 2x2 (box)"]
    assert {r["scene"] for r in rows} == {"default (explicit)"}
    for r in rows:
        assert 0.0 <= r["stability_changed_pct"] <= 100.0 and r["error_mean_levels"] >= 0.0
    assert (tmp_path / "contact_sheet.png").stat().st_size > 0
