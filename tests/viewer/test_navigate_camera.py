"""The viewer's camera is kept between UI frames (navigate.make_camera): it must still follow every
camera parameter, the aspect and the scene, and a caller moving its copy must not move the next one."""

import numpy as np

from app.params import Params
from app.render.camera import Camera
from app.scene.generators import build_scene
from app.viewer.navigate import make_camera


def _same(a: Camera, b: Camera) -> bool:
    return (np.array_equal(a.position, b.position) and np.array_equal(a.target, b.target)
            and (a.fov, a.near, a.far) == (b.fov, b.near, b.far))


def test_the_kept_camera_follows_parameters_aspect_and_scene():
    p = Params()
    scene = build_scene(p)
    other = build_scene(p.replace(**{"scene.length": 3.0}))
    first = make_camera(p, scene, 16 / 9)
    assert _same(first, Camera.from_params(p, scene, aspect=16 / 9))
    first.position[:] = 0.0                                    # a caller moving its copy
    assert _same(make_camera(p, scene, 16 / 9), Camera.from_params(p, scene, aspect=16 / 9))
    for changed, s, aspect in ((p.replace(**{"camera.azimuth": 77.0}), scene, 16 / 9),
                               (p.replace(**{"camera.fov": 20.0}), scene, 16 / 9),
                               (p.replace(**{"camera.target": (0.1, 0.0, 0.2)}), scene, 16 / 9),
                               (p, scene, 0.5), (p, other, 16 / 9)):
        assert _same(make_camera(changed, s, aspect), Camera.from_params(changed, s, aspect=aspect))
    # a look parameter is not a camera parameter: the kept camera is still right
    look = p.replace(**{"look.exposure": 1.0})
    assert _same(make_camera(look, scene, 16 / 9), Camera.from_params(look, scene, aspect=16 / 9))


def test_two_aspects_asked_in_turn_are_both_kept(monkeypatch):
    """A UI frame asks for the camera at the viewport's aspect and at the render size's: both stay kept,
    so alternating between them frames the scene once each, not once a call."""
    import app.viewer.navigate as navigate

    p = Params()
    scene = build_scene(p)
    calls = []
    real = Camera.from_params

    def counting(*args, **kwargs):
        calls.append(1)
        return real(*args, **kwargs)
    monkeypatch.setattr(navigate.Camera, "from_params", counting)
    monkeypatch.setattr(navigate, "_cameras", [])
    for _ in range(5):
        for aspect in (900 / 701, 450 / 350):
            assert _same(navigate.make_camera(p, scene, aspect), real(p, scene, aspect=aspect))
    assert len(calls) == 2
