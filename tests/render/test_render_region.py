"""Renderer.render(region=...): a frame built tile by tile equals the frame rendered whole.

The viewer refines slow frames in strips across UI frames (app/viewer/display.py: StripJob), so every
tile must draw exactly what the whole frame draws there and leave the other pixels alone.
"""

from __future__ import annotations

import numpy as np
import pytest

from app.params import Params
from app.render.camera import Camera
from app.scene.generators import build_scene

SIZE = (96, 64)


def _tiles(size, nx: int, ny: int):
    """Uneven tiles (the last row and column take the remainder), GL origin bottom-left."""
    w, h = size
    xs = np.linspace(0, w, nx + 1).astype(int)
    ys = np.linspace(0, h, ny + 1).astype(int)
    return [(int(x0), int(y0), int(x1 - x0), int(y1 - y0))
            for y0, y1 in zip(ys[:-1], ys[1:]) for x0, x1 in zip(xs[:-1], xs[1:])]


@pytest.fixture()
def furball(renderer):
    p = Params({"scene.generator": "furball", "fibers.rings": 6})
    scene = build_scene(p)
    renderer.set_scene(scene)
    return p, Camera.from_params(p, scene)


@pytest.mark.parametrize("mode", ["exact", "fast"])
def test_a_frame_drawn_in_tiles_equals_the_frame_drawn_whole(renderer, furball, mode):
    p, cam = furball
    outputs = ("color", "ids", "geom")
    whole = renderer.render(p, cam, SIZE, outputs=outputs, mode=mode)
    assert whole.hit.mean() > 0.1, "the scene should cover a good part of the frame"
    # poison the target first: every pixel must come from a tile, none from an earlier frame
    renderer.render(p, Camera.from_params(p.replace(**{"camera.azimuth": 120.0}), renderer.scene), SIZE,
                    outputs=("draw",), mode=mode)
    for tile in _tiles(SIZE, 3, 4):
        frame = renderer.render(p, cam, SIZE, outputs=("draw",), mode=mode, region=tile)
        assert frame.draws > 0
    tiled = renderer.render(p, cam, SIZE, outputs=outputs, mode=mode, region=(0, 0, 0, 0))
    np.testing.assert_array_equal(tiled.ids, whole.ids)
    np.testing.assert_array_equal(tiled.color, whole.color)
    np.testing.assert_array_equal(tiled.geom, whole.geom)


def test_a_region_clears_and_draws_only_its_rectangle(renderer, furball):
    p, cam = furball
    before = renderer.render(p, cam, SIZE, outputs=("ids",), mode="exact").ids
    moved = Camera.from_params(p.replace(**{"camera.azimuth": 120.0}), renderer.scene)
    x, y, w, h = 10, 20, 30, 16
    after = renderer.render(p, moved, SIZE, outputs=("ids",), mode="exact", region=(x, y, w, h)).ids
    inside = np.zeros(SIZE[::-1], bool)
    inside[SIZE[1] - y - h:SIZE[1] - y, x:x + w] = True         # read-backs are top row first
    np.testing.assert_array_equal(after[~inside], before[~inside])
    whole_moved = renderer.render(p, moved, SIZE, outputs=("ids",), mode="exact").ids
    np.testing.assert_array_equal(after[inside], whole_moved[inside])
    assert (after[inside] != before[inside]).any(), "the camera move should change the region"
    # and the scissor is gone afterwards: a plain render covers the whole frame again
    again = renderer.render(p, cam, SIZE, outputs=("ids",), mode="exact").ids
    np.testing.assert_array_equal(again, before)


def test_cost_and_msaa_honour_the_region_too(renderer, furball):
    p, cam = furball
    p = p.replace(**{"quality.msaa": 4})
    whole = renderer.render(p, cam, SIZE, outputs=("color", "cost"), mode="exact")
    for tile in _tiles(SIZE, 2, 3):
        tiled = renderer.render(p, cam, SIZE, outputs=("color", "cost"), mode="exact", region=tile)
    np.testing.assert_array_equal(tiled.cost, whole.cost)
    np.testing.assert_array_equal(tiled.color, whole.color)
