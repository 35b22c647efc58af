"""Scenes the benches share: here, not in suites.py, so a suite module can use one without importing the
registry of suites (which imports every suite module)."""

from __future__ import annotations

import numpy as np

from ..params import Params
from ..render.camera import Camera
from ..scene.containers import Scene
from ..scene.generators import guide_polyline


def overlapping_scene(n: int, per_ring: int, seed: int = 7) -> tuple[Params, Scene, Camera]:
    """``n`` upright containers scattered in a fixed slab seen edge-on, so they hide each other more the
    more there are; the camera does not move with ``n``."""
    p = Params({"fibers.rings": 10, "fibers.phi_step": 360.0 / per_ring, "fibers.fiber_radius": 0.01,
                "scene.radius": 0.2})
    rng = np.random.default_rng(seed)
    roots = np.stack([rng.uniform(-1.5, 1.5, n), rng.uniform(-0.45, 0.45, n), np.zeros(n)], 1)
    guides = [guide_polyline(r, [0, 0, 1], 1.5, 1, 0.0) for r in roots]
    scene = Scene.from_polylines(guides, 0.2, name="overlapping", origin=np.zeros(3))
    cam = Camera(position=np.array([6.0, 0.0, 1.2]), target=np.array([0.0, 0.0, 0.75]), fov=30.0,
                 near=2.0, far=10.0)
    return p, scene, cam
