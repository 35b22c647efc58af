"""Shared helpers for the rendering tests: build a scene, point a camera, compare ids."""

from __future__ import annotations

import numpy as np

from app import reference
from app.params import Params
from app.render.camera import Camera
from app.scene.generators import build_scene


def setup(renderer, values: dict, camera: dict | None = None):
    p = Params(values)
    scene = build_scene(p)
    renderer.set_scene(scene)
    cam_p = p.replace(**{f"camera.{k}": v for k, v in (camera or {}).items()})
    return p, scene, Camera.from_params(cam_p, scene)


def reference_ids(scene, p, cam: Camera, size) -> np.ndarray:
    """(H, W, 3) int64: guide + 1, ring, fiber from the float64 reference (0, -1, -1 on a miss)."""
    w, h = size
    ro, rd = cam.rays(w, h)
    hits = reference.brute_nearest(scene, p, ro, rd, t_near=cam.near)
    g = np.where(hits.hit, hits.guide + 1, 0)
    return np.stack([g, hits.ring, hits.fiber], -1).reshape(h, w, 3)


def gpu_ids(frame) -> np.ndarray:
    ids = frame.ids.astype(np.int64)
    hit = ids[..., 0] > 0
    return np.stack([ids[..., 0], np.where(hit, ids[..., 1], -1), np.where(hit, ids[..., 2], -1)], -1)
