"""Antialiasing gives the same picture whichever way a pixel finds its containers (quality.visibility), and
each mode does what it says on the default preset, where auto picks the proxies: MSAA 2 keeps the colour,
MSAA 4 filters the fibers' edges, supersample 4 shows no background through a container's silhouette.
The predictions are the single-ray frames the modes are made of (no AA, which test_visibility holds to the
walk and the walk to the float64 reference) and a box-filtered reference of jittered single-ray frames."""

from __future__ import annotations

import numpy as np
import pytest

from app.bench.antialias import reference_offsets, to_linear, to_srgb_levels
from app.presets import find_preset
from app.render.camera import Camera
from app.render.renderer import MSAA_PATTERNS, supersample_offsets
from app.scene.generators import build_scene

SIZE = (160, 90)
# levels (of 255) the two strategies may differ by: each sample is the same fiber, shaded alike; the mean of
# the samples is rounded once, so one level covers float reordering in the sum
TOLERANCE = 1.0
MODES = {"supersample 2": {"quality.supersample": 2}, "supersample 4": {"quality.supersample": 4},
         "msaa 2": {"quality.msaa": 2}, "msaa 4": {"quality.msaa": 4}}


@pytest.fixture()
def default(renderer):
    # the unfiltered paths these tests are about: the filtered mode (the default since #16) always walks
    # and has its own tests (test_filter.py; its tiles: test_render_region.py, test_lookdev.py)
    p = find_preset("default").params.replace(**{"quality.supersample": 1, "quality.msaa": 0,
                                                 "quality.filter": "off"})
    scene = build_scene(p)
    cam = Camera.from_params(p, scene, aspect=SIZE[0] / SIZE[1])
    renderer.set_scene(scene)
    assert renderer.visibility(p, cam, SIZE) == "proxies", "the default preset should take the proxies"
    return renderer, p, cam


def _render(renderer, p, cam, values=None, visibility="proxies", **kw):
    q = p.replace(**{"quality.visibility": visibility, **(values or {})})
    return renderer.render(q, cam, SIZE, **kw)


def _samples(renderer, p, cam, offsets):
    """Single-ray frames at sub-pixel ``offsets`` (auto visibility: the proxies here)."""
    return [renderer.render(p, cam, SIZE, outputs=("color",), offset=o, antialias=False) for o in offsets]


def _box_reference(renderer, p, cam, n=8):
    lin = np.mean([to_linear(f.color) for f in _samples(renderer, p, cam, reference_offsets(n))], 0)
    return to_srgb_levels(lin)


@pytest.mark.parametrize("mode", list(MODES))
def test_proxies_and_walk_give_the_same_picture(default, mode):
    renderer, p, cam = default
    outputs = ("color", "ids")
    proxies = _render(renderer, p, cam, MODES[mode], outputs=outputs)
    walk = _render(renderer, p, cam, MODES[mode], "walk", outputs=outputs)
    assert walk.unfinished == 0
    diff = np.abs(proxies.color.astype(np.int32) - walk.color.astype(np.int32))
    assert (walk.coverage > 0).sum() > 1000, "the default preset should cover a good part of the frame"
    assert diff.max() <= TOLERANCE, (f"{mode}: proxies and walk differ by up to {diff.max()} levels, "
                                     f"in {(diff.max(-1) > TOLERANCE).sum()} pixels")
    differ = np.any(proxies.ids != walk.ids, -1)
    assert differ.sum() == 0, f"{mode}: the nearest sample's fiber differs in {differ.sum()} pixels"


@pytest.mark.parametrize("n", [2, 4])
def test_msaa_filters_fiber_edges_without_shifting_the_colour(default, n):
    renderer, p, cam = default
    ref = _box_reference(renderer, p, cam)
    none = _render(renderer, p, cam, outputs=("color",))
    msaa = _render(renderer, p, cam, {"quality.msaa": n}, outputs=("color",))
    covered = (none.coverage > 0) | (msaa.coverage > 0)
    # a prediction: the mean of single-ray frames at the standard sample positions
    frames = _samples(renderer, p, cam, [(x / 16.0, y / 16.0) for x, y in MSAA_PATTERNS[n]])
    predicted = np.mean([f.color.astype(np.float64) for f in frames], 0)
    assert np.abs(msaa.color - predicted).max() <= 1.0 + 1e-9, f"msaa {n} is not the mean of its samples"
    # inside the silhouette too: the fibers' own edges are sub-pixel there, so MSAA must change those pixels
    inside = np.minimum.reduce([f.coverage for f in frames]) == 1.0
    changed = np.abs(msaa.color.astype(np.int32) - none.color.astype(np.int32)).max(-1) > 4
    assert changed[inside].mean() > 0.3, f"msaa {n} leaves {1 - changed[inside].mean():.0%} of fiber pixels as none"
    err_none = np.abs(none.color - ref).max(-1)[covered].mean()
    err_msaa = np.abs(msaa.color - ref).max(-1)[covered].mean()
    bias = (msaa.color - ref)[covered].mean(0)
    assert err_msaa < 0.85 * err_none, f"msaa {n}: mean error {err_msaa:.1f} levels, none's {err_none:.1f}"
    assert np.abs(bias).max() < 4.0, f"msaa {n} shifts the colour: signed mean error {np.round(bias, 1)} levels"


def test_supersample_shows_no_background_inside_the_silhouette(default):
    renderer, p, cam = default
    ss = _render(renderer, p, cam, {"quality.supersample": 4}, outputs=("color",))
    frames = _samples(renderer, p, cam, supersample_offsets(4))
    # every one of its 16 rays meets a fiber (of whichever container): no background belongs in the pixel
    inside = np.minimum.reduce([f.coverage for f in frames]) == 1.0
    assert inside.sum() > 1000
    seams = inside & (ss.coverage < 1.0)
    assert seams.sum() == 0, f"supersample 4 lets the background through in {seams.sum()} pixels of the silhouette"
    mean = np.mean([f.color.astype(np.float64) for f in frames], 0)
    assert np.abs(ss.color - mean).max() <= 1.0 + 1e-9, "supersample 4 is not the mean of its 16 rays"


@pytest.mark.parametrize("visibility", ["proxies", "walk"])
def test_an_antialiased_frame_drawn_in_tiles_equals_the_frame_drawn_whole(default, visibility):
    renderer, p, cam = default
    q = p.replace(**{"quality.visibility": visibility, "quality.supersample": 2})
    whole = renderer.render(q, cam, SIZE, outputs=("color", "ids"))
    renderer.render(q, cam, SIZE, outputs=("color",), offset=(3.0, 0.0))       # something else to overwrite
    w, h = SIZE
    for tile in ((0, 0, w // 2, h), (w // 2, 0, w - w // 2, h // 3), (w // 2, h // 3, w - w // 2, h - h // 3)):
        tiled = renderer.render(q, cam, SIZE, outputs=("color", "ids"), region=tile)
    np.testing.assert_array_equal(tiled.color, whole.color)
    np.testing.assert_array_equal(tiled.ids, whole.ids)
