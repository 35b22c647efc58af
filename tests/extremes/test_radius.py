"""Case 3: fibers of radius 1e-6, 1e-12, 1e-30 and 0 -- nothing non-finite, radius 0 draws nothing at all,
coverage never grows as the radius shrinks."""

from __future__ import annotations

import numpy as np
import pytest

from app import reference
from app.params import Params
from app.render.camera import Camera
from app.scene.containers import Scene

GUIDES = [np.array([[x, y, 0.0], [x + 0.1, y, 1.0], [x + 0.3, y + 0.1, 2.0]]) for x in (-0.6, 0.0, 0.6)
          for y in (-0.5, 0.5)]


@pytest.mark.parametrize("rings", range(1, 65))
def test_layout_is_finite_at_radius_zero_and_full_radial_jitter(rings):
    """Regression: the innermost ring's slot reaches the axis at full radial jitter (rho - max_dr = 0), and
    the disc half-angle rf / 0 was nan for rf = 0 whenever 1 - (K - 0.5)/K == 0.5/K held exactly (K a
    power of two). The nan reached the shader as a uniform and radius-0 fibers covered the image."""
    for jitter in (0.0, 0.5, 1.0):
        lay = reference.ring_layout(Params({"fibers.rings": rings, "fibers.fiber_radius": 0.0,
                                            "fibers.radial_jitter": jitter, "fibers.angular_jitter": 1.0}))
        for name in ("rho", "max_dr", "max_dphi", "reach"):
            assert np.isfinite(getattr(lay, name)).all(), (rings, jitter, name)
        assert (lay.reach == lay.max_dphi).all(), "a fiber of radius 0 reaches no further than its centre"


@pytest.mark.parametrize("mode", ["exact", "fast", "brute"])
@pytest.mark.parametrize("rings", [8, 64])
def test_radius_zero_draws_nothing(renderer, mode, rings):
    """Regression: with rings a power of two and full radial jitter, radius 0 drew 100-5600 phantom pixels."""
    p = Params({"fibers.rings": rings, "fibers.phi_step": 3.0, "fibers.fiber_radius": 0.0,
                "fibers.radial_jitter": 1.0, "fibers.angular_jitter": 1.0})
    renderer.set_scene(Scene.from_polylines(GUIDES, 0.25))
    cam = Camera([3.5, -2.5, 1.8], [0, 0, 1.0], 35, 0.5, 20)
    frame = renderer.render(p, cam, (96, 72), outputs=("ids", "geom"), mode=mode)
    assert not frame.hit.any(), f"{frame.hit.sum()} pixels show fibers of radius 0"
    assert (frame.geom == 0).all()
