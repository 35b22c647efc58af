"""The two ways a pixel finds its containers (quality.visibility: proxies, walk) name the same fiber in
every pixel, in every mode, and auto picks the one the scene's overlap calls for."""

from __future__ import annotations


import numpy as np
import pytest

from app.render.camera import Camera
from app.render.renderer import WALK_LAYERS, proxy_layers
from tests.support.ids import gpu_ids, reference_ids, setup
from tests.render.test_traversal import SCENES
from tests.support.paths import HAIR_DATA

SIZE = (160, 96)
DATA = HAIR_DATA

SHAPED = [
    ("curled", {"scene.generator": "single", "scene.radius": 1.0, "scene.length": 3.0,
                "shape.curl_amplitude": 0.3, "shape.curl_frequency": 3.0}, {}),
    ("twisted-bent", {"scene.generator": "carpet", "scene.count": 5, "scene.segments": 3, "scene.bend": 50.0,
                      "shape.twist": 1.0, "shape.ellipsoid": 0.5}, {"azimuth": 60.0}),
]


def _render(renderer, p, cam, visibility, mode):
    frame = renderer.render(p.replace(**{"quality.visibility": visibility}), cam, SIZE, outputs=("ids", "geom"),
                            mode=mode)
    assert frame.unfinished == 0, f"{visibility} {mode}: pixels left short of their nearest fiber"
    return frame


@pytest.mark.parametrize("name,values,camera", SCENES + SHAPED, ids=[s[0] for s in SCENES + SHAPED])
def test_walk_and_proxies_name_the_same_fibers(renderer, name, values, camera):
    p, scene, cam = setup(renderer, values, camera)
    walk = _render(renderer, p, cam, "walk", "exact")
    assert walk.hit.sum() > 200, "the scene should show fibers"
    for visibility, mode in (("walk", "brute"), ("proxies", "exact"), ("proxies", "brute")):
        other = _render(renderer, p, cam, visibility, mode)
        differ = np.any(walk.ids != other.ids, -1)       # guide, ring, fiber and container segment
        assert differ.sum() == 0, f"{name}: walk exact and {visibility} {mode} differ in {differ.sum()} pixels"
    hit = walk.hit
    assert np.allclose(walk.geom[hit], _render(renderer, p, cam, "proxies", "exact").geom[hit], rtol=1e-5,
                       atol=1e-6), "the same fiber at the same distance and normal"


@pytest.mark.parametrize("seed", [4, 5])
def test_walk_matches_float64_reference(renderer, seed):
    rng = np.random.default_rng(seed)
    values = {"scene.generator": str(rng.choice(["carpet", "furball", "curved"])),
              "scene.count": int(rng.integers(20, 60)), "scene.seed": seed,
              "scene.segments": int(rng.integers(1, 4)), "scene.bend": float(rng.uniform(0, 60)),
              "scene.taper": float(rng.uniform(0, 0.5)), "quality.visibility": "walk"}
    p, scene, cam = setup(renderer, values)
    frame = renderer.render(p, cam, (96, 64), outputs=("ids",))
    ref = reference_ids(scene, p, cam, (96, 64))
    shown = (ref[..., 0] > 0) | frame.hit
    agree = np.all(ref == gpu_ids(frame), -1)[shown].mean()
    assert shown.sum() > 100 and agree >= 0.999, f"walk vs float64: {agree:.4%} of {shown.sum()} pixels"


def test_fast_walk_stops_at_the_first_container_with_a_hit(renderer):
    p, scene, cam = setup(renderer, {"scene.count": 60, "quality.visibility": "walk"})
    fast = renderer.render(p, cam, SIZE, outputs=("ids", "geom", "cost"), mode="fast")
    exact = renderer.render(p, cam, SIZE, outputs=("ids", "geom", "cost"), mode="exact")
    assert (fast.hit == exact.hit).all(), "fast and exact agree on coverage"
    # where they differ, fast named a farther fiber, never a nearer one
    differ = np.any(fast.ids != exact.ids, -1)
    assert (fast.geom[..., 3][differ] >= exact.geom[..., 3][differ] * (1 - 1e-6)).all()
    assert fast.walk[..., 0].sum() <= exact.walk[..., 0].sum(), "fast traverses no more containers"


def test_auto_takes_the_proxies_for_few_layers_and_the_walk_for_many(renderer):
    # auto's choice is the unfiltered frame's: the filtered one (the default since #16) always walks
    p, scene, cam = setup(renderer, {"quality.filter": "off"})
    assert proxy_layers(scene, cam, SIZE) < WALK_LAYERS
    assert renderer.visibility(p, cam, SIZE) == "proxies"
    assert renderer.visibility(p.replace(**{"quality.filter": "coverage"}), cam, SIZE) == "walk"
    assert renderer.visibility(p.replace(**{"quality.filter": "coverage", "quality.mode": "fast"}), cam,
                               SIZE) == "proxies", "fast mode is not filtered: auto chooses as before"
    p, scene, cam = setup(renderer, {"scene.generator": "furball", "scene.count": 3000, "scene.radius": 0.3,
                                     "quality.filter": "off"})
    assert proxy_layers(scene, cam, SIZE) > WALK_LAYERS
    assert renderer.visibility(p, cam, SIZE) == "walk"
    # a camera inside the hair: some proxy reaches behind it and would cover the whole viewport
    inside = Camera(scene.bounds()[0] * 0.0 + scene.origin, scene.origin + np.array([1.0, 0, 0]), 40, 0.01, 100)
    assert proxy_layers(scene, inside, SIZE) == np.inf


@pytest.mark.skipif(not (DATA / "harolongo.data").is_file(), reason="shared hair data not found")
def test_auto_walks_the_dense_groom(renderer):
    p, scene, cam = setup(renderer, {"scene.generator": "groom", "scene.groom_file": str(DATA / "harolongo.data")})
    assert proxy_layers(scene, cam, (640, 360)) > 10 * WALK_LAYERS
    assert renderer.visibility(p, cam, (640, 360)) == "walk"
