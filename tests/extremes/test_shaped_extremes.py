"""The curl, twist and ellipsoid sliders at their ends, on the default fiber layout: exact equals brute
force in every pixel, no draw runs out of llvmpipe's loop budget (the canary in glsl/fibers/traverse.glsl
would raise the iters output to LOOP_CAP), and no NaN reaches the geometry output."""

from __future__ import annotations

import numpy as np
import pytest

from app.bench.quality import EXTREMES
from app.params import Params
from app.render.camera import Camera
from app.render.renderer import LOOP_CAP
from app.scene.generators import build_scene

SIZE = (64, 40)
CASES = {**EXTREMES, "twist -8 uniform": {"shape.twist": -8.0},
         "twist -8 alternating": {"shape.twist": -8.0, "shape.twist_pattern": "alternating"},
         "twist +8 ramped": {"shape.twist": 8.0, "shape.twist_pattern": "ramped"}}


@pytest.mark.parametrize("name", list(CASES))
def test_extreme_shape_is_exact_in_budget_and_finite(renderer, name):
    p = Params({"scene.count": 3, **CASES[name]})
    scene = build_scene(p)
    renderer.set_scene(scene)
    cam = Camera.from_params(p.replace(**{"camera.elevation": 35.0}), scene)   # every ray climbs
    exact = renderer.render(p, cam, SIZE, outputs=("ids", "iters", "geom"), mode="exact")
    fast = renderer.render(p, cam, SIZE, outputs=("ids", "iters", "geom"), mode="fast")
    brute = renderer.render(p, cam, SIZE, outputs=("ids", "iters"), mode="brute")
    assert exact.hit.sum() > 200, f"{name}: the fibers are out of view"
    for mode, frame in (("exact", exact), ("fast", fast), ("brute", brute)):
        assert frame.iters.max() < LOOP_CAP, f"{name}: a {mode} draw ran out of loop budget"
    for mode, frame in (("exact", exact), ("fast", fast)):
        assert np.isfinite(frame.geom).all(), f"{name}: NaN or inf in the {mode} geometry"
    differ = np.any(exact.ids[..., :3] != brute.ids[..., :3], -1).sum()
    assert differ == 0, f"{name}: {differ} pixels name another fiber than brute force"
    # fast may take a farther fiber, but it visits every candidate until it finds one: same coverage
    assert (fast.hit == brute.hit).all(), f"{name}: fast and brute cover different pixels"
