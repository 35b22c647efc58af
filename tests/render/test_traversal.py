"""The traversal modes against each other and against the float64 reference."""

from __future__ import annotations

import numpy as np
import pytest

from app import reference
from app.params import Params
from app.render.renderer import BRUTE_CHUNK, LOOP_CAP
from tests.support.ids import gpu_ids, reference_ids, setup

SIZE = (160, 96)

# (name, parameters, camera) -- each scene stresses a different part of the traversal
SCENES = [
    ("single-side", {"scene.generator": "single", "scene.radius": 1.0, "scene.length": 4.0},
     {"elevation": 0.0}),
    ("carpet", {}, {}),
    ("max-jitter", {"scene.generator": "single", "scene.radius": 1.0, "scene.length": 3.0,
                    "fibers.radial_jitter": 1.0, "fibers.angular_jitter": 1.0, "fibers.fiber_radius": 0.02},
     {"elevation": 25.0}),
    ("phi1-12rings", {"scene.generator": "single", "scene.radius": 1.0, "scene.length": 3.0,
                      "fibers.rings": 12, "fibers.phi_step": 1.0, "fibers.fiber_radius": 0.008}, {}),
    ("through-caps", {"scene.generator": "single", "scene.radius": 1.0, "scene.length": 1.0,
                      "fibers.length_jitter": 0.0}, {"elevation": 80.0}),
    ("sparse-increment", {"scene.generator": "single", "scene.radius": 1.0, "scene.length": 3.0,
                          "fibers.phi_step": 12.0, "fibers.phi_increment": 5.0, "fibers.even_spacing": 0.5,
                          "fibers.fiber_radius": 0.03}, {"elevation": 60.0}),
    ("tapered-bent", {"scene.generator": "carpet", "scene.count": 6, "scene.segments": 4, "scene.bend": 70.0,
                      "scene.taper": 0.6}, {"azimuth": 100.0}),
    ("furball", {"scene.generator": "furball", "scene.count": 40, "scene.radius": 0.2}, {}),
]


@pytest.mark.parametrize("name,values,camera", SCENES, ids=[s[0] for s in SCENES])
def test_exact_equals_brute(renderer, name, values, camera):
    p, scene, cam = setup(renderer, values, camera)
    exact = renderer.render(p, cam, SIZE, outputs=("ids",), mode="exact")
    brute = renderer.render(p, cam, SIZE, outputs=("ids",), mode="brute")
    assert exact.hit.sum() > 200, "the scene should show fibers"
    differ = np.any(exact.ids[..., :3] != brute.ids[..., :3], -1)
    assert differ.sum() == 0, f"{name}: {differ.sum()} pixels differ between exact and brute"


def test_fast_is_close_but_cheaper(renderer):
    p, scene, cam = setup(renderer, {"fibers.radial_jitter": 1.0, "fibers.angular_jitter": 1.0})
    fast = renderer.render(p, cam, SIZE, outputs=("ids", "cost"), mode="fast")
    exact = renderer.render(p, cam, SIZE, outputs=("ids", "cost"), mode="exact")
    assert (fast.hit == exact.hit).all(), "fast and exact must agree on coverage"
    assert fast.cost[..., 0].sum() <= exact.cost[..., 0].sum()


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_glsl_matches_float64_reference(renderer, seed):
    rng = np.random.default_rng(seed)
    values = {"scene.generator": str(rng.choice(["carpet", "furball", "curved"])),
              "scene.count": int(rng.integers(3, 12)), "scene.seed": seed,
              "scene.segments": int(rng.integers(1, 4)), "scene.bend": float(rng.uniform(0, 60)),
              "scene.taper": float(rng.uniform(0, 0.5)),
              "fibers.rings": int(rng.integers(2, 12)), "fibers.phi_step": float(rng.uniform(1, 20)),
              "fibers.radial_jitter": float(rng.uniform()), "fibers.angular_jitter": float(rng.uniform()),
              "fibers.seed": seed}
    values["fibers.fiber_radius"] = 0.5 / values["fibers.rings"] * float(rng.uniform(0.5, 1.0))
    camera = {"azimuth": float(rng.uniform(-180, 180)), "elevation": float(rng.uniform(-30, 80))}
    p, scene, cam = setup(renderer, values, camera)
    size = (128, 96)
    frame = renderer.render(p, cam, size, outputs=("ids",), mode="exact")
    ref = reference_ids(scene, p, cam, size)
    got = gpu_ids(frame)
    hit = (ref[..., 0] > 0) | (got[..., 0] > 0)
    same = np.all(ref == got, -1)[hit]
    assert hit.sum() > 100
    assert same.mean() >= 0.999, f"{(~same).sum()} of {hit.sum()} hit pixels disagree with float64"


def test_brute_chunks_stay_under_the_loop_cap(renderer):
    """72,000 fibers per container: brute force needs two draws, and no invocation may pass llvmpipe's
    65,535 loop iterations (it would stop silently and miss fibers)."""
    values = {"scene.generator": "single", "scene.radius": 1.0, "scene.length": 2.0,
              "fibers.rings": 20, "fibers.phi_step": 0.1, "fibers.fiber_radius": 0.002}
    p, scene, cam = setup(renderer, values)
    total = reference.ring_layout(p).fibers_per_container
    assert total == 72_000 and total > BRUTE_CHUNK
    size = (64, 48)
    brute = renderer.render(p, cam, size, outputs=("ids", "iters"), mode="brute")
    assert brute.draws == 2 * 2  # two chunks, for the ids pass and for the iteration-count pass
    assert 0 < brute.iters.max() < LOOP_CAP
    exact = renderer.render(p, cam, size, outputs=("ids", "iters"), mode="exact")
    assert (exact.ids[..., :3] == brute.ids[..., :3]).all()
    # near the axis a ray sweeps many of the innermost ring's crowded slots, yet stays far from brute force
    assert exact.iters.max() < total / 20


def test_exact_does_far_fewer_tests_than_brute(renderer):
    p, scene, cam = setup(renderer, {})
    exact = renderer.render(p, cam, SIZE, outputs=("cost",), mode="exact").cost
    brute = renderer.render(p, cam, SIZE, outputs=("cost",), mode="brute").cost
    covered = exact[..., 2] > 0
    ratio = brute[..., 0][covered].mean() / exact[..., 0][covered].mean()
    assert ratio >= 50, f"exact does only {ratio:.1f}x fewer fiber tests than brute"


def test_fiber_count_expression_and_exact():
    p = Params({"fibers.rings": 10, "fibers.phi_step": 1.0})
    assert reference.fiber_count(p, 3) == (10800.0, 10800)
    p = Params({"fibers.rings": 2, "fibers.phi_step": 7.0})  # 360 / 7 = 51.43: 51 fibers are drawn
    thesis, exact = reference.fiber_count(p)
    assert thesis == pytest.approx(2 * 360 / 7) and exact == 102
    p = Params({"fibers.rings": 3, "fibers.phi_step": 1.0, "fibers.phi_increment": 1.0})  # thesis 4.3
    assert reference.fiber_count(p)[1] == 360 + 180 + 120
