"""Interpolated child guides (scene.groom_children, app/scene/grooms/children.py) and the fold rule that
fibers.groom_auto adds them by (defaults.auto_children, segments.fold_fraction).

Children are containers, so every renderer, the export and the float64 reference take them as they take any
rows: the rendering tests here hold a scene with children to brute force and to the float64 reference, and
check that the control changes the image and stays finite at its extremes.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from app.params import BY_KEY, Params
from app.render.camera import Camera
from app.scene.grooms import children, defaults, groom_scene, resample_many
from app.scene.grooms.groom import Groom
from app.scene.grooms.segments import MAX_TURN_DEG, auto_segments, fold_fraction, joint_turns
from tests.support.ids import gpu_ids, reference_ids
from tests.support.paths import HAIR_DATA

DATA = HAIR_DATA
needs_data = pytest.mark.skipif(not DATA.is_dir(), reason=f"shared hair data not found at {DATA}")
SIZE = (128, 96)


def _helix(root, curl: float, turns: float, length: float, phase: float, n: int = 48) -> np.ndarray:
    """A strand hanging from ``root`` along -z, curling around its own axis at radius ``curl``."""
    t = np.linspace(0.0, 1.0, n)
    a = phase + 2.0 * np.pi * turns * t
    return np.asarray(root, np.float64) + np.stack(
        [curl * (np.cos(a) - np.cos(phase)), curl * (np.sin(a) - np.sin(phase)), -length * t], axis=1)


def curly_groom(side: int = 4, spacing: float = 1.0, curl: float = 0.4, seed: int = 0) -> Groom:
    """side x side strands one ``spacing`` apart, each a helix of radius ``curl`` (two turns over a length
    of 4) at its own phase: root-spacing containers of 0.75 are wider than the curl, so they fold."""
    rng = np.random.default_rng(seed)
    strands = [_helix((i * spacing, j * spacing, 0.0), curl, 2.0, 4.0, rng.random() * 2 * np.pi)
               for i in range(side) for j in range(side)]
    return Groom(Path("curly.hair"), "hair", strands)


def straight_groom(side: int = 4) -> Groom:
    return Groom(Path("straight.hair"), "hair",
                 [np.array([[i, j, 0.0], [i + 0.1, j, -2.0], [i + 0.2, j, -4.0]]) for i in range(side)
                  for j in range(side)])


def _params(**values) -> Params:
    return Params({"scene.generator": "groom", "scene.groom_file": "curly.hair",
                   **{k.replace("__", "."): v for k, v in values.items()}})


# --------------------------------------------------------------------------------------------------
# Roots, blend, settle
# --------------------------------------------------------------------------------------------------
def test_children_are_rooted_on_a_disc_around_their_guide():
    guides = resample_many(curly_groom().strands, 12)
    roots, parents = children.child_roots(guides, 5, seed=3)
    S = len(guides)
    assert roots.shape == (5 * S, 3) and parents.tolist() == list(range(S)) * 5       # child-major
    spacing = children.root_spacing(guides[:, 0])
    off = roots - guides[parents, 0]
    first = guides[:, 1] - guides[:, 0]
    first /= np.linalg.norm(first, axis=1, keepdims=True)
    assert np.all(np.linalg.norm(off, axis=1) <= spacing[parents] * (1 + 1e-12))
    assert np.abs((off * first[parents]).sum(axis=1)).max() < 1e-12                   # in the root's normal plane
    assert np.linalg.norm(off, axis=1).min() > 0.3 * spacing.min()                    # none on the guide itself
    again, _ = children.child_roots(guides, 5, seed=3)
    other, _ = children.child_roots(guides, 5, seed=4)
    assert np.array_equal(roots, again) and not np.allclose(roots, other)


def test_a_child_on_a_guide_root_is_that_guide_and_blends_stay_between_shapes():
    guides = resample_many(curly_groom().strands, 12)
    at_roots, nearest = children.blend(guides, guides[:, 0], np.arange(len(guides)))
    np.testing.assert_allclose(at_roots, guides, atol=1e-9)
    assert nearest.tolist() == list(range(len(guides)))
    # two guides with different shapes: a child between them has a shape between theirs, point by point
    a = np.stack([np.zeros(9), np.zeros(9), -np.linspace(0, 4, 9)], 1)
    b = a + np.stack([np.linspace(0, 2, 9) ** 2, np.zeros(9), np.zeros(9)], 1) + [3.0, 0.0, 0.0]
    two = np.stack([a, b])
    kid, near = children.blend(two, np.array([[1.0, 0.0, 0.0]]), np.array([0]))
    shape = kid[0] - kid[0, 0]
    lo, hi = np.minimum(a - a[0], b - b[0]), np.maximum(a - a[0], b - b[0])
    assert np.all(shape >= lo - 1e-12) and np.all(shape <= hi + 1e-12) and near[0] == 0
    assert np.all(shape[1:, 0] < (b - b[0])[1:, 0])                       # nearer a, so more like a than b


def test_with_children_keeps_the_guides_and_narrows_the_containers():
    guides = resample_many(curly_groom().strands, 12)
    grown = children.with_children(guides, 3, seed=1)
    assert len(grown.polylines) == 4 * len(guides) and grown.guides == len(guides)
    assert np.array_equal(grown.polylines[:len(guides)], guides)
    assert grown.narrow == pytest.approx(0.5) and children.radius_scale(0) == 1.0
    none = children.with_children(guides, 0)
    assert none.polylines is not None and len(none.polylines) == len(guides) and none.narrow == 1.0


def test_a_child_that_folds_takes_its_nearest_guides_shape():
    guides = resample_many(straight_groom(2).strands, 4)
    grown = children.with_children(guides, 1, seed=0)
    kinked = grown.polylines.copy()
    S = len(guides)
    kinked[S, 3] = kinked[S, 1]                                            # a 180-degree fold in child 0
    out, unfolded = grown.settle(kinked, MAX_TURN_DEG)
    g = grown.nearest[S]
    assert unfolded == 1 and np.allclose(out[S] - out[S, 0], guides[g] - guides[g, 0])
    assert np.array_equal(out[:S], kinked[:S]) and np.array_equal(out[S + 1:], kinked[S + 1:])
    assert joint_turns(out).max() <= MAX_TURN_DEG


# --------------------------------------------------------------------------------------------------
# Curl and fold
# --------------------------------------------------------------------------------------------------
def test_curl_radius_is_the_circle_that_turns_as_much():
    arc = [np.stack([5.0 * np.cos(a), 5.0 * np.sin(a), np.zeros_like(a)], 1) for a in
           [np.linspace(0, 3.0, 200)] * 3]
    # 199 chords turn by 198 steps of the 199 the arc spans: 0.5 % more length per turn than the circle
    assert children.curl_radius(arc) == pytest.approx(5.0 * 199 / 198, rel=1e-4)
    assert children.curl_radius(straight_groom().strands) > 1e3
    assert math.isinf(children.curl_radius([np.array([[0.0, 0, 0], [0, 0, 1.0]])]))


def test_fold_fraction_is_the_inner_rim_running_backwards():
    # one joint turning by 90 degrees between pieces of length 1: a radius r folds when r tan(45) > 1/2
    corner = np.array([[[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, -1.0]]])
    assert fold_fraction(corner, 0.49) == 0.0 and fold_fraction(corner, 0.51) == 1.0
    straight = np.array([[[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 0.0, -2.0]]])
    assert fold_fraction(straight, 1e6) == 0.0 and fold_fraction(straight[:, :2], 1.0) == 0.0


def test_auto_children_only_where_containers_fold():
    curly = curly_groom()
    R = 0.75                                                               # root spacing 1
    n = defaults.auto_children(curly.strands, R)
    assert 0 < n <= children.MAX_CHILDREN
    def folds(k: int) -> float:
        r = R * children.radius_scale(k)
        return fold_fraction(resample_many(curly.strands, auto_segments(curly.strands, np.full(16, r))[0]), r)

    assert folds(0) > defaults.FOLD_TRIGGER
    assert folds(n) <= defaults.MAX_FOLD < folds(n - 1)                   # the fewest that bring it there
    assert defaults.auto_children(straight_groom().strands, R) == 0
    assert defaults.auto_children(curly.strands, 0.05) == 0               # thin containers do not fold
    assert children.MAX_CHILDREN == BY_KEY["scene.groom_children"].hi


# --------------------------------------------------------------------------------------------------
# The scene
# --------------------------------------------------------------------------------------------------
def test_the_scene_holds_the_guides_and_their_children():
    groom = curly_groom()
    plain = groom_scene(groom, _params(scene__segments=8))
    kids = groom_scene(groom, _params(scene__segments=8, scene__groom_children=3))
    assert plain.n_guides == 16 and kids.n_guides == 64 and kids.n_segments == 64 * 8
    np.testing.assert_allclose(kids.segments[:, 3].max(), 0.5 * plain.segments[:, 3].max(), rtol=1e-6)
    # the guides' own containers come first, on the same axes (the radius is the only change)
    np.testing.assert_allclose(kids.segments[:plain.n_segments, 0:3] + kids.origin,
                               plain.segments[:, 0:3] + plain.origin, atol=1e-5)
    assert kids.source.children == 3 and any(x.startswith("children") for x in kids.source_info())
    assert "1 / sqrt(1 + 3)" in kids.source.radius_reason


@needs_data
def test_children_take_their_strands_colours():
    from app.scene.grooms import load_groom

    groom = load_groom(DATA / "Curly_100.ply")
    p = Params({"scene.generator": "groom", "scene.groom_file": str(DATA / "Curly_100.ply"),
                "scene.groom_children": 2})
    scene = groom_scene(groom, p)
    S = groom.n_strands
    assert scene.guide_colors is not None and len(scene.guide_colors) == 3 * S
    np.testing.assert_array_equal(scene.guide_colors[S:2 * S], scene.guide_colors[:S])


@pytest.mark.parametrize("n", [1, BY_KEY["scene.groom_children"].hi])
def test_extremes_stay_finite(n):
    scene = groom_scene(curly_groom(), _params(scene__groom_children=n))
    assert np.isfinite(scene.segments).all() and scene.n_guides == 16 * (1 + n)
    assert (scene.segments[:, 3] > 0).all()


# --------------------------------------------------------------------------------------------------
# Rendering: the control changes the image; exact == brute; the float64 reference agrees
# --------------------------------------------------------------------------------------------------
FILL = {"fibers.rings": 4, "fibers.phi_step": 12.0, "fibers.fiber_radius": 0.06}


def _render(renderer, n: int, mode: str = "exact", camera=None, **extra):
    p = _params(scene__segments=8, scene__groom_children=n, **{k.replace(".", "__"): v for k, v in FILL.items()},
                **extra)
    scene = groom_scene(curly_groom(side=3), p)
    renderer.set_scene(scene)
    cam = camera or Camera.from_params(p.replace(**{"camera.elevation": 10.0}),
                                       groom_scene(curly_groom(side=3), _params(scene__segments=8)),
                                       aspect=SIZE[0] / SIZE[1])
    return p, scene, cam, renderer.render(p, cam, SIZE, outputs=("ids", "color", "geom"), mode=mode)


def test_children_change_the_image(renderer):
    _, _, cam, before = _render(renderer, 0)
    _, _, _, after = _render(renderer, 4, camera=cam)
    changed = np.any(before.color != after.color, -1).mean()
    assert changed > 0.05, f"children changed only {changed:.2%} of the pixels"
    assert after.hit.mean() > 0.05 and np.isfinite(after.geom).all()


@pytest.mark.parametrize("n", [3, BY_KEY["scene.groom_children"].hi])
def test_children_exact_equals_brute_and_the_reference(renderer, n):
    p, scene, cam, exact = _render(renderer, n)
    brute = renderer.render(p, cam, SIZE, outputs=("ids",), mode="brute")
    assert exact.hit.sum() > 500
    differ = np.any(exact.ids[..., :3] != brute.ids[..., :3], -1)
    assert differ.sum() == 0, f"{differ.sum()} pixels differ between exact and brute"
    assert np.isfinite(exact.geom).all()
    ref = reference_ids(scene, p, cam, SIZE)
    got = gpu_ids(exact)
    hit = (ref[..., 0] > 0) | (got[..., 0] > 0)
    same = np.all(ref == got, -1)[hit]
    assert same.mean() >= 0.999, f"{(~same).sum()} of {hit.sum()} hit pixels disagree with float64"


# --------------------------------------------------------------------------------------------------
# fibers.groom_auto: children for Curly_100 alone; what a person sets wins
# --------------------------------------------------------------------------------------------------
@needs_data
@pytest.mark.parametrize("name", ["sintel_hair.tfx", "Bangs_100.hair", "Ratboy_mohawk.tfx", "harolongo.data",
                                  "Curly_100.ply"])
def test_groom_auto_gives_children_where_containers_fold(name):
    from app.presets import resolve_params
    from app.scene.grooms import scene_from_groom

    p, _ = resolve_params(str(DATA / name), ["fibers.groom_auto=true"])
    if name != "Curly_100.ply":
        assert p["scene.groom_children"] == 0
        return
    assert p["scene.groom_children"] > 0
    scene = scene_from_groom(p)
    guides = load_polylines(scene)[:scene.n_guides // (1 + p["scene.groom_children"])]
    r = float(np.median(scene.source.radii))
    assert fold_fraction(guides, r) <= defaults.MAX_FOLD < defaults.FOLD_TRIGGER < fold_fraction(
        guides, r / children.radius_scale(p["scene.groom_children"]))
    plain, _ = resolve_params(str(DATA / name), ["fibers.groom_auto=true", "scene.groom_children=0"])
    assert plain["scene.groom_children"] == 0 and plain["fibers.rings"] > p["fibers.rings"]   # wider containers
    off, _ = resolve_params(str(DATA / name), ["fibers.groom_auto=false"])
    assert off["scene.groom_children"] == 0 and off["fibers.rings"] == 10


def load_polylines(scene) -> np.ndarray:
    """The guides of a scene of equal-length guides, back from its rows: (guides, segments + 1, 3)."""
    rows = scene.segments.astype(np.float64)
    per = scene.source.segments
    p0 = rows[:, 0:3].reshape(-1, per, 3)
    return np.concatenate([p0, rows[per - 1::per, 4:7][:, None]], axis=1) + scene.origin


@needs_data
def test_the_blend_export_carries_the_children():
    """export-blend builds its prisms and colour attributes from the scene's rows, children included."""
    from app.export.blend import color_face_attributes, container_boxes
    from app.scene.grooms import scene_from_groom

    p = Params({"scene.generator": "groom", "scene.groom_file": str(DATA / "Curly_100.ply"),
                "scene.groom_children": 2})
    scene = scene_from_groom(p)
    plain = scene_from_groom(p.replace(**{"scene.groom_children": 0}))
    _, _, sizes, rows = container_boxes(scene.segments)
    _, _, plain_sizes, _ = container_boxes(plain.segments)
    assert len(sizes) == 3 * len(plain_sizes) and set(np.unique(rows)) == set(range(scene.n_segments))
    colours = color_face_attributes(scene.segments, rows, scene.guide_colors)
    assert all(len(v) == len(rows) and np.isfinite(v).all() for v in colours.values())
