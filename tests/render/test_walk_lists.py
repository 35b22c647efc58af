"""The walk's draws after the first run over a list of the pixels still walking, packed 8 to a SIMD batch
(glsl/stages/walk.frag: walked_pixel, renderer.py: list_rectangle): every listed pixel is walked once per
draw, whatever the target's size, and the frame stays exact."""

from __future__ import annotations

import numpy as np
import pytest

from app.render.renderer import list_rectangle
from tests.support.ids import setup


def _entries(width: int, height: int, blocks: int) -> np.ndarray:
    """walk.frag's entry number of every fragment of the rectangle (y up, as gl_FragCoord)."""
    y, x = np.mgrid[0:height, 0:width]
    if blocks:
        return (((y >> 1) * (width >> 2) + (x >> 2)) << 3) | ((y & 1) << 2) | (x & 3)
    return y * width + x


@pytest.mark.parametrize("size", [(640, 360), (900, 701), (5, 3), (3, 7), (1, 1), (4, 1), (7, 2)])
def test_the_rectangle_holds_every_entry_once_and_fits_the_target(size):
    w, h = size
    for count in sorted(c for c in {1, 2, 7, 8, 9, w, w * h // 3 + 1, w * h - 1, w * h} if 0 < c <= w * h):
        width, height, blocks = list_rectangle(count, size)
        assert 0 < width <= w and 0 < height <= h, (size, count)
        k = _entries(width, height, blocks)
        listed = np.sort(k[k < count])
        assert np.array_equal(listed, np.arange(count)), (size, count, blocks)
        if w >= 4 and count <= (w - w % 4) * (h - h % 2):
            assert blocks == 1, (size, count)
            # a 4x2 block (a SIMD batch) takes 8 consecutive entries
            block = k[0:2, 0:4]
            assert block.max() - block.min() == 7


OVERLAPPING = {"scene.generator": "furball", "scene.count": 400, "scene.radius": 0.3, "scene.seed": 3,
               "quality.visibility": "walk"}


@pytest.mark.parametrize("size", [(96, 64), (13, 7), (5, 3), (3, 3), (1, 1)])
def test_listed_draws_keep_the_walk_exact(renderer, size):
    """Pixels that need many containers go through many listed draws (and, on targets too narrow for 4x2
    blocks, rows of entries); the frame still names brute force's fiber in every pixel."""
    p, scene, cam = setup(renderer, OVERLAPPING)
    exact = renderer.render(p, cam, size, outputs=("ids", "cost"), mode="exact")
    brute = renderer.render(p, cam, size, outputs=("ids",), mode="brute")
    assert exact.unfinished == 0
    assert exact.hit.any()
    assert np.array_equal(exact.ids, brute.ids)
    if size == (96, 64):
        # the listed draws ran: pixels that needed 3 or more draws exist and finished
        assert exact.walk[..., 2].max() >= 3


def test_the_resolve_still_shades_every_pixel_that_shows_something(renderer):
    """mark_shown.frag keeps the resolve off the pixels the walk ran on that show nothing; in the filtered
    mode a pixel whose footprint meets fibers shows their colour even without a hit at its centre, and
    must not be skipped."""
    p, scene, cam = setup(renderer, {**OVERLAPPING, "scene.count": 60, "fibers.fiber_radius": 0.002,
                                     "quality.filter": "coverage"})
    f = renderer.render(p, cam, (96, 64), outputs=("color", "ids"), mode="exact")
    background = np.round(np.clip(np.asarray(p["look.background"]), 0, 1) ** (1 / 2.2) * 255)
    colour_only = (f.coverage > 0.05) & ~f.hit
    assert colour_only.sum() > 20, "the scene should have pixels covered without a fiber at their centre"
    assert np.any(np.abs(f.color[colour_only].astype(float) - background) > 2, -1).mean() > 0.9
    plain = renderer.render(p.replace(**{"quality.filter": "off"}), cam, (96, 64), outputs=("color", "ids"))
    assert np.array_equal(plain.ids, f.ids)
    assert (plain.coverage[~plain.hit] == 0).all() and (plain.coverage[plain.hit] > 0).all()
