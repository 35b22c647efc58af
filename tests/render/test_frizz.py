"""Frizz and noise (shape.frizz, shape.noise, shape.noise_frequency): each fiber sways its own way.

The displacement comes from the fiber's hash (app/fibers/shape.py: frizz_offset), shares the curl's half a
ring width (displacement_scale), and the shaped traversal's bands, reach and chord rule take it
(docs/shaped-traversal.md), so exact equals brute and the GLSL follows the float64 reference.
"""

from __future__ import annotations

import numpy as np
import pytest

from app import fibers
from app.params import Params
from app.render import explicit, renderer as R
from tests.export.test_osl_export import blender_test, gl_vs_cycles, same_fiber
from tests.support.ids import assert_matches_reference, setup

SIZE = (128, 96)
ONE = {"scene.generator": "single", "scene.radius": 1.0, "scene.length": 4.0, "fibers.rings": 5,
       "fibers.phi_step": 8.0, "fibers.fiber_radius": 0.03}
LOOKS = {
    "frizz-straight": {**ONE, "shape.frizz": 0.8},
    "noise-straight": {**ONE, "shape.noise": 1.0, "shape.noise_frequency": 24.0},
    "frizz-curled": {**ONE, "shape.curl_amplitude": 0.35, "shape.curl_frequency": 6.0, "shape.frizz": 0.7,
                     "shape.noise": 0.5},
    "frizz-wave-twisted": {**ONE, "shape.curl_amplitude": 0.3, "shape.curl_pattern": "wave",
                           "shape.twist": 0.6, "shape.frizz": 1.0, "shape.noise": 1.0},
    "frizz-thesis-hash": {**ONE, "fibers.hash": "thesis", "shape.frizz": 0.6, "shape.noise": 0.4},
    "frizz-bent-ellipsoid": {"scene.count": 3, "scene.segments": 3, "scene.bend": 40.0, "scene.taper": 0.3,
                             "fibers.rings": 5, "fibers.phi_step": 10.0, "fibers.fiber_radius": 0.04,
                             "shape.ellipsoid": 0.5, "shape.frizz": 1.0, "shape.noise": 0.6},
}
# the ends of the ranges, all at once, and grazing views (tests/extremes' spirit)
EXTREMES = {
    "frizz-max-curl-max": {**ONE, "shape.curl_amplitude": 0.5, "shape.curl_frequency": 64.0, "shape.frizz": 1.0,
                           "shape.noise": 1.0, "shape.noise_frequency": 64.0},
    "frizz-thin": {**ONE, "fibers.fiber_radius": 1e-3, "shape.frizz": 1.0, "shape.noise": 1.0},
    "frizz-thick": {**ONE, "fibers.rings": 1, "fibers.fiber_radius": 0.5, "shape.frizz": 1.0,
                    "shape.noise": 1.0, "shape.noise_frequency": 64.0},
}


def test_defaults_are_off_and_build_nothing_in():
    p = Params({})
    sh = fibers.Shape.from_params(p)
    assert p["shape.frizz"] == 0 and p["shape.noise"] == 0 and not sh.frizzed and not sh.curved
    assert not R.is_shaped(p) and R.model_defines(p, "exact", False)["SHAPE_FRIZZ"] == 0
    # the curl alone keeps its amplitude bit for bit (curl / rings, as before frizz existed)
    curled = Params({"shape.curl_amplitude": 0.5, "fibers.rings": 7})
    assert fibers.Shape.from_params(curled).curl_amplitude == 0.5 / 7
    assert fibers.Shape.from_params(curled).displacement == 0.5 / 7


def test_frizz_alone_takes_the_shaped_path():
    p = Params({"shape.frizz": 0.5})
    assert R.is_shaped(p) and fibers.Shape.from_params(p).curved
    assert R.model_defines(p, "exact", False)["SHAPE_FRIZZ"] == 1
    assert R.is_shaped(Params({"shape.noise": 0.2}))


@pytest.mark.parametrize("curl,frizz,noise", [(0.0, 1.0, 1.0), (0.5, 1.0, 0.0), (0.5, 0.0, 1.0),
                                              (0.5, 1.0, 1.0), (0.2, 0.3, 0.5), (0.1, 0.2, 0.3)])
def test_the_displacement_never_leaves_the_slot(curl, frizz, noise):
    rings = 6
    p = Params({"fibers.rings": rings, "shape.curl_amplitude": curl, "shape.frizz": frizz, "shape.noise": noise})
    sh = fibers.Shape.from_params(p)
    assert sh.displacement <= fibers.DISPLACEMENT_LIMIT / rings * (1 + 1e-12)
    # every fiber's offset at every height stays within its share of the bound
    phase = fibers.fiber_random(0, 3, 2, np.arange(4000), fibers.CH_CURL)
    v = np.linspace(0.0, 1.0, 257)[:, None]
    fx, fy = fibers.frizz_offset(sh, v, phase[None])
    assert np.hypot(fx, fy).max() <= (sh.frizz_amplitude + sh.noise_amplitude) * (1 + 1e-12)
    # and the terms keep their proportions: the scale is shared
    if curl + fibers.FRIZZ_WIDTH * frizz + fibers.NOISE_WIDTH * noise <= fibers.DISPLACEMENT_LIMIT:
        assert sh.frizz_amplitude == pytest.approx(fibers.FRIZZ_WIDTH * frizz / rings)


def test_fibers_frizz_each_their_own_way():
    sh = fibers.Shape.from_params(Params({"shape.frizz": 1.0, "shape.noise": 1.0}))
    phase = fibers.fiber_random(0, 0, 1, np.arange(500), fibers.CH_CURL)
    ua, uf, ud, up, un = fibers.frizz_randoms(phase)
    for u in (ua, uf, ud, up, un):
        assert 0.0 <= u.min() and u.max() < 1.0 and 0.4 < u.mean() < 0.6
    # independent of the curl phase they are drawn from, and of each other
    assert abs(np.corrcoef(phase, ud)[0, 1]) < 0.15 and abs(np.corrcoef(ua, uf)[0, 1]) < 0.15
    v = np.linspace(0, 1, 64)[:, None]
    fx, fy = fibers.frizz_offset(sh, v, phase[None])
    assert np.unique(np.round(np.hypot(fx, fy).max(0), 6)).size > 450     # no two fibers sway alike


def test_the_chord_rule_takes_more_pieces_for_faster_noise():
    from app import reference
    base = {"fibers.rings": 4, "fibers.fiber_radius": 0.02, "shape.noise": 1.0}
    lay = fibers.ring_layout(Params(base))
    counts = []
    for f in (2.0, 8.0, 32.0):
        sh = fibers.Shape.from_params(Params({**base, "shape.noise_frequency": f}))
        counts.append(int(reference.chord_pieces(sh, lay, 0.02, 0, 1.0)))
    assert counts[0] < counts[1] < counts[2] <= fibers.MAX_SUB


@pytest.mark.parametrize("name", list(LOOKS))
def test_frizz_changes_the_image(renderer, name):
    p, scene, cam = setup(renderer, LOOKS[name], {"elevation": 25.0})
    keys = ("shape.frizz", "shape.noise")
    plain, _, _ = setup(renderer, {k: v for k, v in LOOKS[name].items() if k not in keys}, {"elevation": 25.0})
    got = renderer.render(p, cam, SIZE, outputs=("ids",), mode="exact").ids
    base = renderer.render(plain, cam, SIZE, outputs=("ids",), mode="exact").ids
    hit = (got[..., 0] > 0) | (base[..., 0] > 0)
    assert hit.sum() > 300
    assert np.any(got[..., :3] != base[..., :3], -1)[hit].mean() > 0.2


@pytest.mark.parametrize("name", list(LOOKS) + list(EXTREMES))
def test_frizz_exact_equals_brute(renderer, name):
    values = {**LOOKS, **EXTREMES}[name]
    for elevation in (25.0, 88.0, -3.0):      # across, nearly along, and grazing
        p, scene, cam = setup(renderer, values, {"elevation": elevation})
        size = (96, 72) if name in EXTREMES else SIZE
        exact = renderer.render(p, cam, size, outputs=("ids", "cost", "color"), mode="exact")
        brute = renderer.render(p, cam, size, outputs=("ids",), mode="brute")
        assert exact.hit.sum() > (50 if name in EXTREMES else 200), (name, elevation)
        differ = np.any(exact.ids[..., :3] != brute.ids[..., :3], -1).sum()
        assert differ == 0, f"{name} at {elevation}: {differ} pixels differ"
        assert exact.cost[..., 3].max() < 65_535 and exact.unfinished == 0 and brute.unfinished == 0
        assert np.isfinite(exact.color).all()


def test_frizz_glsl_matches_float64_reference(renderer):
    looks = [*LOOKS.values(), EXTREMES["frizz-max-curl-max"]]
    assert_matches_reference(renderer, [(values, {"elevation": 25.0}) for values in looks])


def test_the_explicit_baseline_says_it_leaves_frizz_out(ctx):
    # the baseline stores straight fibers (as for the curl, twist and ellipsoid): a comparison must say so
    from app.render.camera import Camera
    from app.scene.generators import build_scene

    p = Params({"scene.count": 3, "fibers.phi_step": 6.0, "shape.frizz": 0.5, "shape.noise": 0.2})
    assert explicit.ignored_shape(p) == ("shape.frizz", "shape.noise")
    assert explicit.ignored_shape(Params({})) == ()
    e = explicit.ExplicitRenderer(ctx)
    try:
        scene = build_scene(p)
        e.set_scene(scene, p)
        with pytest.warns(UserWarning, match="shape.frizz"):
            e.render(p, Camera.from_params(p, scene), (32, 18), outputs=("ids",))
    finally:
        e.release()
        e.release_targets()


def test_frizz_moves_fibers_off_the_baselines_rest_lines_by_at_most_its_bound():
    """The same fibers as the baseline's (frizz draws no placement channel), displaced within the bound:
    the frizzed centre at any height is the rest centre plus at most frizz + noise amplitude."""
    p = Params({"fibers.rings": 5, "fibers.phi_step": 8.0, "shape.frizz": 1.0, "shape.noise": 1.0})
    lay, sh = fibers.ring_layout(p), fibers.Shape.from_params(p)
    cx, cy, _, _, _ = explicit.fiber_centers(lay, np.array([7]))
    ring, j, rx, ry, _ = fibers.all_fibers(lay, 7)
    np.testing.assert_array_equal(cx[0], rx)
    phase = fibers.fiber_randoms(lay, 7, ring, j, fibers.CH_CURL)
    v = np.linspace(0, 1, 33)[:, None]
    fx, fy = fibers.fiber_center_at(sh, rx[None], ry[None], v, ring[None], phase[None])
    d = np.hypot(fx - rx[None], fy - ry[None])
    assert d.max() <= sh.displacement * (1 + 1e-9) and d.max() > 0.5 * sh.displacement



@blender_test
def test_frizz_fiber_ids_match_in_cycles(cycles, renderer, tmp_path):
    """The OSL twin: the exported shader sees the same frizzed fiber as the preview in each pixel."""
    p = Params({"scene.generator": "single", "scene.radius": 0.3, "scene.length": 1.0, "fibers.rings": 5,
                "fibers.phi_step": 9.0, "fibers.fiber_radius": 0.05, "shape.curl_amplitude": 0.3,
                "shape.curl_frequency": 3.0, "shape.twist": 0.5, "shape.frizz": 0.8, "shape.noise": 0.6,
                "camera.elevation": 25.0})
    r = gl_vs_cycles(cycles, renderer, p, tmp_path, "frizz_ids", debug_view=1)
    both = r["gl"] & r["cycles"]
    same = same_fiber(r)
    print(f"frizz: fiber ids agree on {same[both].mean():.4%} of {both.sum()} pixels both cover")
    assert both.sum() > 3000 and r["agree"] >= 0.995
    assert same[both].mean() >= 0.995


def test_frizz_comes_from_presets_set_and_the_osl_export(tmp_path):
    from app.cli import resolve_params
    from app.export import osl as X
    from app.presets import loads_preset
    from tests.support.paths import ROOT

    pre = loads_preset('version = 2\nname = "frizzy"\n[shape]\nfrizz = 0.7\nnoise = 0.3\nnoise_frequency = 20.0\n',
                       "frizzy.toml")
    p = getattr(pre, "params", pre)
    assert (p["shape.frizz"], p["shape.noise"], p["shape.noise_frequency"]) == (0.7, 0.3, 20.0)
    q, _ = resolve_params(str(ROOT / "presets" / "curly-1.toml"), ["shape.frizz=0.4", "shape.noise=1"])
    assert q["shape.frizz"] == 0.4 and q["shape.noise"] == 1.0
    for bad in ({"shape.frizz": 1.5}, {"shape.noise": -0.1}, {"shape.noise_frequency": 65.0}):
        with pytest.raises(Exception, match=next(iter(bad))):
            Params(bad)
    text = X.export_osl(q, tmp_path / "frizzy.osl", "frizzy").read_text()
    assert "float shape_frizz = 0.4" in text and "float shape_noise = 1" in text
    assert "#define VF_CH_FRIZZ_AMP 7" in text and "#define VF_DISPLACEMENT_LIMIT 0.5" in text
