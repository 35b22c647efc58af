"""Tip taper (strand.tip_width, strand.taper_start): each fiber thins toward its own tip.

Held against predictions: the width line against the profile it stands for (app/fibers/taper.py), the
cone interval against dense sampling, the shader against the float64 reference and against its own brute
force, the explicit ribbons against the virtual fibers; and the image changes, stays finite at the ends of
the range, and tip width 1 is today's image.
"""

from __future__ import annotations

import numpy as np
import pytest

from app import fibers, reference
from app.params import ParamError, Params
from app.render.explicit import compare_frames, plan
from app.render.renderer import filtered
from tests.support.ids import assert_matches_reference, gpu_ids, reference_ids, setup

SIZE = (128, 96)
ONE = {"scene.generator": "single", "scene.radius": 1.0, "scene.length": 4.0, "fibers.rings": 5,
       "fibers.phi_step": 8.0, "fibers.fiber_radius": 0.08, "fibers.length_jitter": 0.5}
POINTED = {"strand.tip_width": 0.0, "strand.taper_start": 0.3}
SCENES = {
    # side-on: the cones' flanks and points
    "single-pointed": ({**ONE, **POINTED}, {"elevation": 0.0}),
    # from above the tips, down the fibers: rays steeper than the cones' sides (a < 0)
    "single-from-tips": ({**ONE, "strand.tip_width": 0.2, "strand.taper_start": 0.0}, {"elevation": 70.0}),
    # bent and tapered containers (kappa != 0): the width line is the chord of the profile in Z
    "bent-tapered": ({"scene.count": 4, "scene.segments": 4, "scene.bend": 60.0, "scene.taper": 0.5,
                      "fibers.rings": 4, "fibers.phi_step": 9.0, "fibers.fiber_radius": 0.1,
                      "fibers.length_jitter": 0.6, **POINTED}, {"azimuth": 100.0, "elevation": 15.0}),
    # curved fibers (shaped traversal): the cone about the moving centre, piece by piece
    "curled-pointed": ({**ONE, "shape.curl_amplitude": 0.3, "shape.twist": 0.4, "scene.segments": 3,
                        **POINTED}, {"elevation": 10.0}),
}


# --- the model -------------------------------------------------------------------------------------
def test_width_line_is_the_profile_at_its_knots_and_never_wider():
    """Per segment, L(Z) equals g(v) at the ends of the thinning part, is continuous from segment to
    segment, reaches tip_width at the fiber's own tip, and min(1, L) never exceeds 1 nor falls below 0
    before the tip (kappa != 0: a tapered container)."""
    tp = fibers.Taper(0.25, 0.4)
    v_end = np.array([1.0, 0.83, 0.55, 0.31])
    edges = np.linspace(0.0, 1.0, 6)
    r = np.linspace(1.0, 0.4, 6)                      # container radius at each joint
    h = 0.7
    g = lambda v: np.where(v <= tp.start * v_end, 1.0,  # noqa: E731
                           1.0 - (1.0 - tp.tip_width) * (v - tp.start * v_end) / ((1.0 - tp.start) * v_end))
    for k in range(5):
        v0, v1, r0, r1 = edges[k], edges[k + 1], r[k], r[k + 1]
        kappa = (r1 - r0) / h
        l0, l1 = fibers.taper_line(tp, v0, v1, h / (v1 - v0), r0, kappa, v_end)
        def Z(v, v0=v0, v1=v1, r0=r0, kappa=kappa):
            z = (v - v0) / (v1 - v0) * h
            return z / (r0 + kappa * z)
        for v in (v0, v1, tp.start * v_end, v_end):
            inside = (v >= v0) & (v <= v1) & (v <= v_end) & (v_end > v0) & (v >= tp.start * v_end - 1e-12)
            L = l0 + l1 * Z(np.clip(v, v0, v1))
            np.testing.assert_allclose(np.where(inside, L, 0), np.where(inside, g(np.clip(v, v0, v1)), 0),
                                       atol=1e-12)
        vs = np.linspace(v0, v1, 101)[:, None]
        alive = vs <= v_end
        width = np.minimum(1.0, l0 + l1 * Z(vs))
        assert np.all(width[alive] >= -1e-12) and np.all(width <= 1.0)
        # never wider than the profile's chord allows: between g's values at the segment's ends
        assert np.all(width[alive] >= np.minimum(g(vs), g(np.minimum(v1, v_end)))[alive] - 0.05)


def test_untapered_line_is_the_cylinder():
    l0, l1 = fibers.taper_line(fibers.Taper(1.0, 0.3), 0.2, 0.4, 5.0, 1.0, -0.3, np.array([0.3, 1.0]))
    np.testing.assert_array_equal(l0, 1.0)
    np.testing.assert_array_equal(l1, 0.0)
    assert np.all(fibers.taper_apex(l0, l1) == np.inf)


def test_cone_interval_against_sampling():
    """The interval of every ray in the cone's nappe (radius >= 0) is what dense sampling finds, for rays
    shallower and steeper than its side, along its axis, and parallel to a side line."""
    rng = np.random.default_rng(7)
    n = 1500
    o = rng.normal(size=(n, 2))
    d = rng.normal(size=(n, 2)) * rng.choice([1.0, 1e-3, 0.0], size=(n, 1))
    rho0 = rng.uniform(-1, 2, n)
    rho1 = rng.normal(size=n) * rng.choice([0.0, 1.0, 10.0], n)
    side = np.arange(n) < 50                          # parallel to a side line: |d| = |rho1|
    rho1[side] = np.hypot(d[side, 0], d[side, 1]) * np.sign(rng.normal(size=side.sum()))
    t0, t1 = reference.cone_interval(o[:, 0], o[:, 1], d[:, 0], d[:, 1], 0.0, 0.0, rho0, rho1)
    ts = np.linspace(-20, 20, 20001)
    for i in range(n):
        p = o[i] + ts[:, None] * d[i]
        rho = rho0[i] + rho1[i] * ts
        inside = np.hypot(p[:, 0], p[:, 1]) <= rho
        pred = (ts >= t0[i]) & (ts <= t1[i]) & (rho >= 0)
        assert (inside != pred).sum() <= 2, (i, t0[i], t1[i])


def test_parameters_have_ranges_and_say_what_they_do():
    for bad in ({"strand.tip_width": -0.1}, {"strand.tip_width": 1.5}, {"strand.taper_start": 1.0}):
        with pytest.raises(ParamError, match="strand"):
            Params(bad)
    assert not fibers.tapered(Params({}))
    assert fibers.tapered(Params({"strand.tip_width": 0.99}))


def test_presets_set_and_osl_export_carry_the_taper(tmp_path):
    """A preset's [strand] table, --set and the OSL export's parameter block all reach the two keys; a bad
    value in a preset names the file, the line and the range."""
    from app.export.osl import osl_source
    from app.params import parse_assignment
    from app.presets import PresetError, load_preset, resolve_params

    path = tmp_path / "pointed.toml"
    path.write_text('version = 2\nname = "pointed"\n\n[strand]\ntip_width = 0.1\ntaper_start = 0.6\n')
    p = load_preset(path).params
    assert (p["strand.tip_width"], p["strand.taper_start"]) == (0.1, 0.6)
    assert parse_assignment("strand.tip_width=0") == ("strand.tip_width", 0)
    q, _ = resolve_params("default", ["strand.tip_width=0.25"])
    assert q["strand.tip_width"] == 0.25
    src = osl_source(q)
    assert "strand_tip_width" in src and "strand_taper_start" in src and "0.25" in src
    # a preset's taper is part of its look: --preset puts it on a groom, which keeps its own scene
    from tests.support.paths import HAIR_DATA
    groom = HAIR_DATA / "Bangs_100.hair"
    if groom.exists():
        g, _ = resolve_params(str(groom), [], look=str(path))
        assert g["strand.tip_width"] == 0.1 and g["scene.generator"] == "groom"
    (tmp_path / "bad.toml").write_text('version = 2\n[strand]\ntip_width = 2.0\n')
    with pytest.raises(PresetError, match=r"bad.toml:3.*strand.tip_width.*\[0, 1\]"):
        load_preset(tmp_path / "bad.toml")


# --- the shader ------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", list(SCENES))
def test_tapered_exact_equals_brute(renderer, name):
    values, camera = SCENES[name]
    p, _, cam = setup(renderer, values, camera)
    exact = renderer.render(p, cam, SIZE, outputs=("ids", "cost", "geom"), mode="exact")
    brute = renderer.render(p, cam, SIZE, outputs=("ids",), mode="brute")
    assert exact.hit.sum() > 300
    differ = np.any(exact.ids[..., :3] != brute.ids[..., :3], -1).sum()
    assert differ == 0, f"{name}: {differ} pixels differ"
    assert np.isfinite(exact.geom).all(), "a normal or distance is not finite"
    assert exact.cost[..., 3].max() < 65_535


def test_tapered_glsl_matches_float64_reference(renderer):
    assert_matches_reference(renderer, SCENES.values())


def test_taper_changes_the_image_and_thins_the_tips(renderer):
    """Pointed tips cover fewer pixels than blunt ones, never more (each tapered fiber lies inside its
    cylinder); the shading normal on the cones leans toward the tips. The unfiltered frame: the filtered
    one (the default since #16) ignores the taper (the next test)."""
    base, camera = {**ONE, "quality.filter": "off"}, {"elevation": 0.0}
    p0, scene, cam = setup(renderer, base, camera)
    blunt = renderer.render(p0, cam, SIZE, outputs=("color", "ids", "geom"))
    p1 = p0.replace(**POINTED)
    pointed = renderer.render(p1, cam, SIZE, outputs=("color", "ids", "geom"))
    assert np.any(blunt.color != pointed.color)
    assert pointed.hit.sum() < 0.9 * blunt.hit.sum()
    # every pixel a pointed fiber covers, its blunt cylinder covers (the same fiber or one in front)
    assert np.all(blunt.hit[pointed.hit])
    # partly tapered (tip width 0.5) lies between
    half = renderer.render(p0.replace(**{"strand.tip_width": 0.5}), cam, SIZE, outputs=("ids",))
    assert pointed.hit.sum() < half.hit.sum() < blunt.hit.sum()


def test_a_tapered_look_is_filtered_and_shows_its_tips(renderer):
    """The filtered mode's coverage (glsl/fibers/coverage.glsl) takes each fiber's width where the ray passes
    it. Before it did, filtered blunt and pointed frames of this scene were equal in every pixel (128x96,
    coverage summed 1484.3 both, where the exact hits go 1423 -> 1176) and a tapered look was drawn
    unfiltered; now the filtered pointed frame covers less, as its exact hits do, and keeps their ids."""
    p0, _, cam = setup(renderer, {**ONE, "quality.filter": "coverage"}, {"elevation": 0.0})
    pointed_p = p0.replace(**POINTED)
    assert filtered(p0, "exact") and filtered(pointed_p, "exact")
    pointed = renderer.render(pointed_p, cam, SIZE, outputs=("color", "ids"))
    blunt = renderer.render(p0, cam, SIZE, outputs=("color", "ids"))
    unfiltered = renderer.render(pointed_p.replace(**{"quality.filter": "off"}), cam, SIZE, outputs=("color", "ids"))
    assert np.array_equal(pointed.ids, unfiltered.ids), "ids stay the exact traversal's"
    assert not np.array_equal(pointed.color, unfiltered.color), "the pointed look is filtered"
    blunt_hits = renderer.render(p0.replace(**{"quality.filter": "off"}), cam, SIZE, outputs=("ids",)).hit.sum()
    assert pointed.coverage.sum() < 0.92 * blunt.coverage.sum(), (pointed.coverage.sum(), blunt.coverage.sum())
    assert unfiltered.hit.sum() < 0.9 * blunt_hits


def test_cone_normal_leans_toward_the_tip(renderer):
    """Side-on, the normal of a cone hit leans toward the fibers' tips by the cone's slope: radius
    fiber_radius * r over the thinning length (1 - taper_start) * length (one straight segment); the
    cylinder's is level."""
    p, scene, cam = setup(renderer, {**ONE, **POINTED, "fibers.length_jitter": 0.0}, {"elevation": 0.0})
    frame = renderer.render(p, cam, SIZE, outputs=("ids", "geom"))
    up = np.asarray(scene.segments[0, 4:7], np.float64) - scene.segments[0, 0:3]
    up /= np.linalg.norm(up)
    n_up = frame.geom[..., :3] @ up
    rows = np.nonzero(frame.hit.any(1))[0]
    top, bottom = rows.min(), rows.max()               # image rows: the tips are at the top
    near_tip = frame.hit.copy()
    near_tip[top + (bottom - top) // 4:] = False
    near_root = frame.hit.copy()
    near_root[:bottom - (bottom - top) // 4] = False
    slope = ONE["fibers.fiber_radius"] * ONE["scene.radius"] / ((1 - POINTED["strand.taper_start"])
                                                                 * ONE["scene.length"])
    assert np.median(n_up[near_tip]) == pytest.approx(np.sin(np.arctan(slope)), rel=0.02)
    assert abs(np.median(n_up[near_root])) < 1e-3


@pytest.mark.parametrize("values", [
    {"strand.tip_width": 0.0, "strand.taper_start": 0.0},
    {"strand.tip_width": 0.0, "strand.taper_start": 0.95},
    {"strand.tip_width": 0.999, "strand.taper_start": 0.95},
    {"strand.tip_width": 0.0, "fibers.length_jitter": 1.0},
    {"strand.tip_width": 0.0, "fibers.fiber_radius": 0.0},
    {"strand.tip_width": 0.0, "fibers.rings": 1, "fibers.fiber_radius": 0.5},
])
def test_finite_at_the_ends_of_the_range(renderer, values):
    """No NaN or infinity in colour, normal or distance; exact == brute; at radius 0 nothing is drawn."""
    p, scene, cam = setup(renderer, {**ONE, "scene.segments": 2, "scene.taper": 0.6, **values},
                          {"elevation": 40.0})
    exact = renderer.render(p, cam, (80, 60), outputs=("color", "ids", "geom"), mode="exact")
    brute = renderer.render(p, cam, (80, 60), outputs=("ids",), mode="brute")
    assert np.isfinite(exact.geom).all()
    assert np.all(exact.ids[..., :3] == brute.ids[..., :3])
    if p["fibers.fiber_radius"] == 0.0:
        assert not exact.hit.any()
    else:
        assert exact.hit.any()


@pytest.mark.parametrize("radius", [1e-6, 0.1])
@pytest.mark.parametrize("elevation", [89.9, -89.9, 0.0])
def test_grazing_and_axial_rays_on_pointed_fibers(renderer, radius, elevation):
    """Rays down the fibers onto their points (steeper than any cone's side), up from below the roots, and
    level across them; fibers from 1e-6 to the ring's full half width: finite, exact == brute, and the
    float64 judge agrees."""
    values = {**ONE, "fibers.fiber_radius": radius, "fibers.rings": 5, **POINTED}
    p, scene, cam = setup(renderer, values, {"elevation": elevation, "azimuth": 17.0})
    size = (64, 48)
    exact = renderer.render(p, cam, size, outputs=("color", "ids", "geom"), mode="exact")
    brute = renderer.render(p, cam, size, outputs=("ids",), mode="brute")
    assert np.isfinite(exact.geom).all()
    assert np.all(exact.ids[..., :3] == brute.ids[..., :3])
    ref = reference_ids(scene, p, cam, size)
    got = gpu_ids(exact)
    hit = (ref[..., 0] > 0) | (got[..., 0] > 0)
    if radius > 1e-3:                                  # 1e-6 is far below a pixel: nothing need show
        assert hit.sum() > 30
    assert (np.all(ref == got, -1) | ~hit).sum() >= hit.size - max(1, hit.sum() // 200)


def test_tip_width_one_is_todays_image(renderer):
    """At tip width 1 the shader is built without the cone (TAPER 0): ids and colour are those of a
    parameter set that never mentions the taper, whatever taper_start says."""
    p, scene, cam = setup(renderer, {**ONE}, {"elevation": 10.0})
    a = renderer.render(p, cam, SIZE, outputs=("color", "ids"))
    b = renderer.render(p.replace(**{"strand.taper_start": 0.1}), cam, SIZE, outputs=("color", "ids"))
    assert np.array_equal(a.ids, b.ids) and np.array_equal(a.color, b.color)


# --- the explicit baseline -------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["single-pointed", "bent-tapered"])
def test_explicit_ribbons_taper_like_the_virtual_fibers(renderer, explicit, name):
    """The ribbons place the same fibers, now pointed: the same coverage and ids as the virtual renderer
    (as closely as tests/test_explicit.py holds them untapered), and fewer pixels than untapered ribbons."""
    values, camera = SCENES[name]
    p, scene, cam = setup(renderer, values, camera)
    size = (160, 120)
    virtual = renderer.render(p, cam, size, outputs=("ids",))
    explicit.set_scene(scene, p)
    assert explicit.gpu_bytes == plan(scene, p).gpu_bytes
    ribbons = explicit.render(p, cam, size, outputs=("ids", "geom"))
    m = compare_frames(virtual, ribbons)
    assert m["covered_iou"] >= 0.97, m
    assert m["id_agree"] >= 0.90, m
    assert np.isfinite(ribbons.geom).all()
    blunt = explicit.render(p.replace(**{"strand.tip_width": 1.0}), cam, size, outputs=("ids",))
    assert (ribbons.ids[..., 0] > 0).sum() < 0.95 * (blunt.ids[..., 0] > 0).sum()


# --- the OSL twin in Cycles --------------------------------------------------------------------------
from tests.export.test_blender_export import SIZE as CYCLES_SIZE  # noqa: E402
from tests.export.test_blender_export import _export, _render_like_a_farm, agreement, blender_test  # noqa: E402

CYCLES_SETS = ("strand.tip_width=0", "strand.taper_start=0.3", "fibers.fiber_radius=0.04",
               "fibers.length_jitter=0.5")


@blender_test
@pytest.mark.blender
@pytest.mark.parametrize("name", ["default", "twisted-curled-1"])
def test_osl_twin_tapers_like_the_preview(name, tmp_path):
    """The exported shader in Cycles names the preview's fibers on pointed tips (straight and curved
    traversals), and its exact mode equals its brute force in every pixel."""
    from app import cli
    gl = tmp_path / "gl.npy"
    sets = [a for s in CYCLES_SETS for a in ("--set", s)]
    assert cli.main(["render", name, *sets, "--size", CYCLES_SIZE, "--output", "id", "-o", str(gl)]) == 0
    ids = {}
    for mode in ("exact", "brute"):
        _export(name, tmp_path / f"{mode}.blend", *CYCLES_SETS, f"quality.mode={mode}")
        _render_like_a_farm(tmp_path / f"{mode}.blend", tmp_path / f"{mode}.npy", "--ids")
        ids[mode] = np.load(tmp_path / f"{mode}.npy")
    coverage, same_id, both = agreement(ids["exact"], np.load(gl))
    assert both > 500
    assert coverage >= 0.97 and same_id >= 0.95, (coverage, same_id)
    assert np.array_equal(ids["exact"], ids["brute"])
