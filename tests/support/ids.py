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


def reference_agreement(renderer, scenes, size=(96, 72)) -> tuple[int, int]:
    """(pixels where GLSL and the float64 reference name the same fiber, pixels either hits), summed over
    ``scenes``: (values, camera) pairs for :func:`setup`, rendered in exact mode."""
    agree = total = 0
    for values, camera in scenes:
        p, scene, cam = setup(renderer, values, camera)
        got = gpu_ids(renderer.render(p, cam, size, outputs=("ids",), mode="exact"))
        ref = reference_ids(scene, p, cam, size)
        hit = (ref[..., 0] > 0) | (got[..., 0] > 0)
        agree += int(np.all(ref == got, -1)[hit].sum())
        total += int(hit.sum())
    return agree, total


def assert_matches_reference(renderer, scenes, size=(96, 72), share=0.999, min_pixels=3000) -> None:
    """GLSL matches the float64 reference on at least ``share`` of the hit pixels of ``scenes``."""
    agree, total = reference_agreement(renderer, scenes, size)
    assert total > min_pixels, f"only {total} hit pixels: the scenes lost their fibers"
    assert agree / total >= share, f"{total - agree} of {total} hit pixels disagree with float64"
