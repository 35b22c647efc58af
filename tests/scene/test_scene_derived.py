"""A scene's derived geometry (bounds, end points) is worked out once and must equal the direct formulas:
the viewer asks for it several times a UI frame (issue 12), and the camera frames the scene from it."""

import math

import numpy as np

from app.params import Params
from app.render.camera import Camera
from app.scene.containers import Scene
from app.scene.generators import build_scene


def _direct_bounds(scene: Scene):
    s = scene.segments.astype(np.float64)
    r = np.maximum(s[:, 3], s[:, 7])[:, None]
    lo = np.minimum(s[:, 0:3], s[:, 4:7]) - r
    hi = np.maximum(s[:, 0:3], s[:, 4:7]) + r
    return lo.min(0) + scene.origin, hi.max(0) + scene.origin


def _direct_framing(scene: Scene, target, direction, fov, aspect, margin=1.06):
    # the formula before the cache: every end point with its radius fits the view
    right, up, _ = Camera(target + direction, target, fov).basis()
    th = math.tan(math.radians(fov) / 2)
    seg = scene.segments.astype(np.float64)
    pts = np.concatenate([seg[:, 0:3], seg[:, 4:7]]) + scene.origin
    rad = np.concatenate([seg[:, 3], seg[:, 7]])
    r = pts - target
    need = np.maximum((np.abs(r @ right) + rad) / (th * aspect), (np.abs(r @ up) + rad) / th) * margin \
        + r @ direction + rad
    extent = float(np.linalg.norm(pts.max(0) - pts.min(0))) + 2 * float(rad.max())
    return max(need.max(), extent * 0.05, 1e-9)


def test_cached_bounds_equal_the_formula_and_cannot_be_changed_through_a_result():
    scene = build_scene(Params().replace(**{"scene.count": 30, "scene.segments": 3}))
    lo, hi = scene.bounds()
    want_lo, want_hi = _direct_bounds(scene)
    np.testing.assert_array_equal(lo, want_lo)
    np.testing.assert_array_equal(hi, want_hi)
    lo[:] = 1e9                                     # a caller scribbling on its copy
    np.testing.assert_array_equal(scene.bounds()[0], want_lo)
    pts, rad = scene.end_points()
    assert not pts.flags.writeable and not rad.flags.writeable
    assert pts.shape == (2 * scene.n_segments, 3) and rad.shape == (2 * scene.n_segments,)


def test_a_translated_scene_has_its_own_bounds():
    scene = build_scene(Params())
    scene.bounds(), scene.end_points()
    moved = scene.translated([10.0, -5.0, 2.0])
    np.testing.assert_allclose(moved.bounds()[0], scene.bounds()[0] + [10.0, -5.0, 2.0])
    np.testing.assert_allclose(moved.end_points()[0], scene.end_points()[0] + [10.0, -5.0, 2.0])


def test_the_framing_camera_equals_the_direct_formula_from_every_side():
    scene = build_scene(Params().replace(**{"scene.count": 40, "scene.segments": 4, "scene.bend": 0.5}))
    for az, el, aspect in ((0.0, 0.0, 16 / 9), (37.0, 20.0, 1.0), (200.0, -60.0, 0.5), (90.0, 89.9, 3.0)):
        p = Params().replace(**{"camera.azimuth": az, "camera.elevation": el})
        cam = Camera.from_params(p, scene, aspect=aspect)
        dist = float(np.linalg.norm(cam.position - cam.target))
        a, e = math.radians(az), math.radians(el)
        direction = np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])
        want = _direct_framing(scene, cam.target, direction, p["camera.fov"], aspect)
        assert math.isclose(dist, want, rel_tol=1e-12), (az, el, dist, want)
