"""Colour models and antialiasing options."""

from __future__ import annotations

import numpy as np
import pytest

from app.params import ParamError, Params
from app.render import look
from tests.support.ids import setup


def test_melanin_matches_cycles_principled_hair():
    # Cycles: melanin_qty = -log(max(1 - melanin, 1e-4)); eumelanin = qty (1 - redness), pheomelanin = qty
    # redness; sigma = eu (0.506, 0.841, 1.653) + pheo (0.343, 0.733, 1.924)
    sigma = look.melanin_to_sigma(0.5, 0.25)
    q = -np.log(0.5)
    want = q * 0.75 * np.array([0.506, 0.841, 1.653]) + q * 0.25 * np.array([0.343, 0.733, 1.924])
    assert np.allclose(sigma, want)
    assert np.allclose(look.melanin_to_sigma(0.0, 0.7), 0.0)
    # the preview colour inverts Cycles' sigma_from_reflectance: (log(c) / factor)^2 gives sigma back
    c = look.sigma_to_color(sigma)
    assert np.allclose((np.log(c) / look.roughness_factor(0.3)) ** 2, sigma)


def test_more_melanin_is_darker_and_redness_is_redder():
    dark = look.base_color(Params({"look.color_mode": "melanin", "look.melanin": 0.8}))
    light = look.base_color(Params({"look.color_mode": "melanin", "look.melanin": 0.2}))
    assert sum(dark) < sum(light)
    red = look.base_color(Params({"look.color_mode": "melanin", "look.melanin": 0.3, "look.melanin_redness": 1.0}))
    assert red[0] / red[2] > light[0] / light[2]


@pytest.mark.parametrize("option", [{"quality.supersample": 3}, {"quality.msaa": 2}, {"quality.msaa": 4}])
def test_antialiasing_softens_edges_and_keeps_ids(renderer, option):
    # the one-ray frame these options antialias: the filtered one (the default since #16) is partly covered
    # already (test_filter.py)
    base = {"scene.generator": "single", "scene.radius": 1.0, "scene.length": 3.0, "fibers.phi_step": 6.0,
            "fibers.fiber_radius": 0.02, "fibers.rings": 4, "quality.filter": "off"}
    p, scene, cam = setup(renderer, base)
    plain = renderer.render(p, cam, (96, 96), outputs=("color", "ids"))
    p2, _, _ = setup(renderer, {**base, **option})
    smooth = renderer.render(p2, cam, (96, 96), outputs=("color", "ids"))
    # ids come from the centre/nearest ray: identical coverage of the same fibers
    assert (smooth.hit == plain.hit).mean() > 0.97
    # a one-ray pixel is covered or not; an antialiased one can be partly covered
    partial = lambda f: ((f.coverage > 0.01) & (f.coverage < 0.99)).mean()  # noqa: E731
    assert partial(plain) == 0
    assert partial(smooth) > 0.01


def test_msaa_counts_the_driver_cannot_do_are_refused_clearly(renderer):
    p, scene, cam = setup(renderer, {"quality.msaa": 3})
    with pytest.raises(ParamError, match="use 0, 2, 4 or 8"):
        renderer.render(p, cam, (16, 16))
    if renderer.ctx.max_samples < 8:
        p, scene, cam = setup(renderer, {"quality.msaa": 8})
        with pytest.raises(ParamError, match="supports at most"):
            renderer.render(p, cam, (16, 16))
