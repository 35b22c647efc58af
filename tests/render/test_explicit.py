"""The explicit (conventional) baseline: same fibers as the virtual ones, exact byte counts, a budget."""

from __future__ import annotations

import numpy as np
import pytest

from app import reference
from app.params import Params
from app.render.camera import Camera
from app.render.explicit import (INSTANCE_BYTES, ROW_BYTES, ExplicitBudgetError, ExplicitRenderer,
                                 compare_frames, estimate_bytes, fiber_centers, plan, segment_fibers)
from app.render.renderer import Renderer
from app.scene.generators import build_scene

SIZE = (160, 96)

LAYOUTS = [
    {},
    {"fibers.hash": "thesis", "fibers.rings": 4, "fibers.phi_step": 7.0, "fibers.phi_increment": 3.0},
    {"fibers.rings": 12, "fibers.even_spacing": 1.0, "fibers.fiber_radius": 0.02, "fibers.seed": 9,
     "fibers.radial_jitter": 1.0, "fibers.angular_jitter": 1.0, "fibers.length_jitter": 0.9},
]

# (name, parameters, camera): side view, a bent and tapered carpet, top-down through the tips
SCENES = [
    ("single-side", {"scene.generator": "single", "scene.radius": 1.0, "scene.length": 4.0,
                     "fibers.phi_step": 4.0}, {"camera.elevation": 0.0}),
    ("carpet", {"scene.count": 8, "fibers.phi_step": 3.0}, {}),
    ("tapered-bent", {"scene.count": 5, "scene.segments": 4, "scene.bend": 70.0, "scene.taper": 0.6,
                      "fibers.phi_step": 3.0}, {"camera.azimuth": 100.0}),
]


@pytest.mark.parametrize("values", LAYOUTS)
def test_placement_is_the_reference_placement(values):
    """Same fibers: the numpy generator equals reference.all_fibers (and the per-fiber shading randoms
    equal reference.fiber_random) fiber by fiber, for both hashes."""
    p = Params(values)
    lay = reference.ring_layout(p)
    guides = np.array([0, 3, 17, 123456])
    cx, cy, v_end, tint, rough = fiber_centers(lay, guides)
    for gi, g in enumerate(guides):
        ring, j, rx, ry, rv = reference.all_fibers(lay, int(g))
        np.testing.assert_array_equal(cx[gi], rx)
        np.testing.assert_array_equal(cy[gi], ry)
        np.testing.assert_array_equal(v_end[gi], rv)
        np.testing.assert_array_equal(tint[gi], reference.fiber_random(lay.seed, g, ring, j, reference.CH_TINT))
        np.testing.assert_array_equal(rough[gi], reference.fiber_random(lay.seed, g, ring, j, reference.CH_ROUGH))


@pytest.mark.parametrize("name,values,camera", SCENES, ids=[s[0] for s in SCENES])
def test_every_explicit_point_lies_on_its_virtual_fiber(name, values, camera):
    """A prediction, not a golden: map points of each stored (segment, fiber) ribbon axis back into the
    segment's unit space (reference.segment); they must sit on the fiber's (cx, cy), inside the segment's
    joint planes, and stop where the guide parameter reaches v_end."""
    p = Params(values)
    scene = build_scene(p)
    lay = reference.ring_layout(p)
    F = lay.fibers_per_container
    recs, length = segment_fibers(scene, lay, np.arange(scene.n_segments))
    half = recs[:, :5].copy().view(np.float16).astype(np.float64).reshape(scene.n_segments, F, 5)
    for si, row in enumerate(scene.segments):
        seg = reference.segment(row)
        _, _, cx, cy, v_end = reference.all_fibers(lay, seg.guide)
        d, t0, t1 = half[si, :, :3], half[si, :, 3], half[si, :, 4]
        p0, p1 = row[0:3].astype(np.float64), row[4:7].astype(np.float64)
        r0, r1 = float(row[3]), float(row[7])
        for t in (t0, 0.5 * (t0 + t1), t1):
            P = p0 + t[:, None] * (p1 - p0) + (r0 + t * (r1 - r0))[:, None] * d
            local = (P - seg.p0) @ np.stack([seg.ex, seg.ey, seg.ez]).T
            w = seg.r0 + seg.kappa * local[:, 2]
            ok = length[si] > 0
            # half floats: 2^-11 relative on |d| <= 1, so a few 1e-4 of the container radius
            np.testing.assert_allclose(local[ok, 0] / w[ok], cx[ok], atol=1.5e-3)
            np.testing.assert_allclose(local[ok, 1] / w[ok], cy[ok], atol=1.5e-3)
            # inside the joint planes (leaning planes included), with the half-float slack along the axis
            slack = 2e-3 * seg.h + 1e-6
            assert np.all(local[ok] @ seg.n0 >= -slack)
            assert np.all(local[ok] @ seg.n1 <= seg.n1[2] * seg.h + slack)
        # the end: the guide parameter at t1 is v_end where the fiber stops inside this segment
        v_at_t1 = seg.v0 + (seg.v1 - seg.v0) * t1
        stops = (v_end < seg.v1) & (v_end > seg.v0) & (length[si] > 0)
        np.testing.assert_allclose(v_at_t1[stops], v_end[stops], atol=2e-3 * (seg.v1 - seg.v0) + 1e-9)
        # a fiber that stopped in an earlier segment has no length here
        assert np.all(length[si][v_end <= seg.v0] == 0)


@pytest.mark.parametrize("name,values,camera", SCENES, ids=[s[0] for s in SCENES])
def test_estimate_equals_allocated_bytes(explicit, name, values, camera):
    p = Params(values)
    scene = build_scene(p)
    expected = estimate_bytes(scene, p)
    stats = explicit.set_scene(scene, p)
    assert explicit.gpu_bytes == expected == stats.gpu_bytes
    F = reference.ring_layout(p).fibers_per_container
    assert expected == scene.n_segments * (F * INSTANCE_BYTES + ROW_BYTES)
    assert plan(scene, p).fibers == scene.n_guides * F


def test_over_budget_refuses_before_allocating(ctx):
    p = Params({"scene.count": 50, "fibers.phi_step": 0.5})
    scene = build_scene(p)
    need = estimate_bytes(scene, p)
    e = ExplicitRenderer(ctx, budget_bytes=need - 1)
    with pytest.raises(ExplicitBudgetError) as info:
        e.set_scene(scene, p)
    message = str(info.value)
    assert e.gpu_bytes == 0 and e.scene is None, "nothing may be allocated on refusal"
    assert f"{plan(scene, p).fibers:,} fibers" in message
    assert "budget" in message and "virtual method" in message and "budget_bytes" in message
    assert info.value.needed == need and info.value.budget == need - 1
    # exactly at the budget it fits
    e.budget_bytes = need
    e.set_scene(scene, p)
    assert e.gpu_bytes == need
    e.release()


def test_refusal_keeps_the_previous_scene(explicit):
    small = Params({"scene.count": 4})
    scene = build_scene(small)
    explicit.set_scene(scene, small)
    before = explicit.gpu_bytes
    explicit.budget_bytes = before
    big = small.replace(**{"fibers.phi_step": 0.25})
    with pytest.raises(ExplicitBudgetError):
        explicit.set_scene(scene, big)
    assert explicit.gpu_bytes == before


def test_renders_fibers(explicit):
    # the opaque ribbons: the filtered frame (the default since #16) colours pixels without an id too
    # (test_explicit_filter.py)
    p = Params({"scene.count": 8, "fibers.phi_step": 3.0, "quality.filter": "off"})
    scene = build_scene(p)
    explicit.set_scene(scene, p)
    cam = Camera.from_params(p, scene)
    frame = explicit.render(p, cam, SIZE, outputs=("color", "ids", "geom"))
    hit = frame.hit
    assert hit.sum() > 500
    bg8 = np.round(np.asarray(p["look.background"]) ** (1 / 2.2) * 255).astype(np.uint8)
    assert np.all(frame.color[~hit] == bg8)
    assert np.any(frame.color[hit] != bg8, -1).mean() > 0.99
    ids = frame.ids[hit]
    assert ids[:, 0].max() <= scene.n_guides and ids[:, 3].max() < scene.n_segments
    lay = reference.ring_layout(p)
    assert np.all(ids[:, 2] < lay.n[ids[:, 1]]), "fiber index within its ring"
    assert np.all(frame.geom[hit][:, 3] > cam.near)


def test_a_changed_fiber_parameter_changes_the_image(explicit):
    p = Params({"scene.count": 6, "fibers.phi_step": 3.0})
    scene = build_scene(p)
    explicit.set_scene(scene, p)
    cam = Camera.from_params(p, scene)
    first = explicit.render(p, cam, SIZE, outputs=("ids",))
    second = explicit.render(p.replace(**{"fibers.seed": 5}), cam, SIZE, outputs=("ids",))  # regenerates
    assert np.any(first.ids != second.ids)
    thinner = explicit.render(p.replace(**{"fibers.fiber_radius": 0.004}), cam, SIZE, outputs=("ids",))
    assert thinner.hit.sum() < first.hit.sum()


@pytest.mark.parametrize("name,values,camera", SCENES, ids=[s[0] for s in SCENES])
def test_coverage_agrees_with_virtual(ctx, explicit, name, values, camera):
    """The explicit image shows the same fibers where the virtual one does.

    Floor, from the two ways they can differ: (1) half-float storage moves a ribbon's edge by up to ~2.5%
    of a fiber's radius and the ribbon's flat silhouette differs from the cylinder's by (r/d)^2, so only
    pixel centres within a few percent of a fiber's width of its edge can flip; (2) ribbons have no end
    caps, so tips seen end-on are missed. Here fibers are 1-3 pixels wide and cover 10-25% of the image:
    (1) flips well under 1% of covered pixels. Measured: >= 99.98% of all pixels agree; the floors below
    leave room for llvmpipe/LLVM versions without letting a misplaced fiber (which moves whole rows of
    pixels) through. Ids agree less (>= 95%) because where two fibers cross within a fiber radius in depth
    the ribbon (depth at the axis) and the cylinder (depth at its surface) can pick different ones."""
    p = Params(values)
    scene = build_scene(p)
    cam = Camera.from_params(p.replace(**camera), scene)
    virtual = Renderer(ctx)
    virtual.set_scene(scene)
    explicit.set_scene(scene, p)
    fv = virtual.render(p, cam, SIZE, outputs=("ids",), mode="exact")
    fe = explicit.render(p, cam, SIZE, outputs=("ids",))
    virtual.release_targets()
    m = compare_frames(fv, fe)
    assert m["covered_virtual"] > 0.05, "the scene should show fibers"
    assert m["coverage_agree"] >= 0.995, m
    assert m["covered_iou"] >= 0.97, m
    assert m["id_agree"] >= 0.90, m


def test_curved_fibers_are_named_not_silently_dropped(explicit):
    p = Params({"scene.count": 3, "fibers.phi_step": 6.0, "shape.curl_amplitude": 0.3})
    scene = build_scene(p)
    explicit.set_scene(scene, p)
    with pytest.warns(UserWarning, match="shape.curl_amplitude"):
        explicit.render(p, Camera.from_params(p, scene), (32, 18), outputs=("ids",))
