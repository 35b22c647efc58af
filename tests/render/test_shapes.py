"""Curved fibers (curl, twist, ellipsoid), bent and tapered chains, and robust frames."""

from __future__ import annotations

import numpy as np
import pytest

from app import reference
from app.params import Params
from app.render.camera import Camera
from app.scene.containers import Scene, orthonormal_x
from tests.support.ids import assert_matches_reference, setup

SIZE = (128, 96)
ONE = {"scene.generator": "single", "scene.radius": 1.0, "scene.length": 4.0, "fibers.rings": 5,
       "fibers.phi_step": 8.0, "fibers.fiber_radius": 0.03}
SHAPES = {
    "twist-uniform": {**ONE, "shape.twist": 0.5},
    "twist-ramped": {**ONE, "shape.twist": 0.8, "shape.twist_pattern": "ramped"},
    "twist-alternating": {**ONE, "shape.twist": 0.6, "shape.twist_pattern": "alternating"},
    "curl-helix": {**ONE, "shape.curl_amplitude": 0.4, "shape.curl_frequency": 6.0},
    "curl-wave": {**ONE, "shape.curl_amplitude": 0.4, "shape.curl_frequency": 5.0, "shape.curl_pattern": "wave"},
    "ellipsoid": {**ONE, "shape.ellipsoid": 0.9, "scene.segments": 6},
    "combined-bent": {"scene.count": 3, "scene.segments": 3, "scene.bend": 40.0, "scene.taper": 0.3,
                      "fibers.rings": 5, "fibers.phi_step": 10.0, "fibers.fiber_radius": 0.04,
                      "shape.twist": 1.0, "shape.twist_pattern": "ramped", "shape.curl_amplitude": 0.3,
                      "shape.curl_pattern": "wave", "shape.ellipsoid": 0.5},
}


@pytest.mark.parametrize("name", list(SHAPES))
def test_curved_exact_equals_brute(renderer, name):
    p, scene, cam = setup(renderer, SHAPES[name], {"elevation": 25.0})
    exact = renderer.render(p, cam, SIZE, outputs=("ids", "cost"), mode="exact")
    brute = renderer.render(p, cam, SIZE, outputs=("ids",), mode="brute")
    assert exact.hit.sum() > 300
    differ = np.any(exact.ids[..., :3] != brute.ids[..., :3], -1).sum()
    assert differ == 0, f"{name}: {differ} pixels differ"
    assert exact.cost[..., 3].max() < 65_535


# Exact mode's stop at the best hit's point (shaped.glsl: SHAPED_POINT_STOP) leans on the rest directions
# keeping slot order, which full angular jitter brings to its edge (a fiber's offset reaches half its slot
# less its disc), and on the angles compared staying within half a turn: dense rings, thin fibers, a wide
# curl or frizz, seen across, at a slant and nearly along the fibers (many chord pieces per arc).
POINT_STOP = {"scene.generator": "single", "scene.radius": 1.0, "scene.length": 4.0, "fibers.rings": 8,
              "fibers.phi_step": 2.0, "fibers.fiber_radius": 0.01, "fibers.angular_jitter": 1.0,
              "fibers.radial_jitter": 1.0}


@pytest.mark.parametrize("shape", [{"shape.curl_amplitude": 0.5, "shape.curl_frequency": 9.0},
                                   {"shape.frizz": 1.0, "shape.noise": 0.5, "shape.curl_frequency": 4.0}],
                         ids=["curl", "frizz"])
@pytest.mark.parametrize("elevation", [5.0, 35.0, 80.0])
def test_the_stop_at_the_best_point_keeps_exact_equal_to_brute(renderer, shape, elevation):
    p, scene, cam = setup(renderer, {**POINT_STOP, **shape}, {"elevation": elevation})
    exact = renderer.render(p, cam, SIZE, outputs=("ids", "cost"), mode="exact")
    brute = renderer.render(p, cam, SIZE, outputs=("ids",), mode="brute")
    assert exact.hit.sum() > 300
    differ = np.any(exact.ids[..., :3] != brute.ids[..., :3], -1).sum()
    assert differ == 0, f"elevation {elevation}: {differ} pixels differ"
    assert exact.cost[..., 3].max() < 65_535


# A chord piece's window (shaped.glsl: piece_window) is taken in the frame turned by the twist interpolated
# along the piece where the ray's angle there runs one way, else as the ray's sweep less the twist's range;
# the point stop looks at the edge of each fiber's wedge. Dense, jittered rings, twisted in each pattern,
# with the ellipsoid (its scale changes along a piece) and a curl, seen nearly across, at a slant and
# nearly along the fibers (long pieces that turn by much).
TWISTED_WINDOW = {**POINT_STOP, "shape.ellipsoid": 0.8, "scene.segments": 3}


@pytest.mark.parametrize("shape", [{"shape.twist": 1.5},
                                   {"shape.twist": -2.0, "shape.twist_pattern": "ramped",
                                    "shape.curl_amplitude": 0.3, "shape.curl_frequency": 5.0},
                                   {"shape.twist": 3.0, "shape.twist_pattern": "alternating",
                                    "shape.curl_amplitude": 0.2, "shape.curl_frequency": 3.0,
                                    "shape.curl_pattern": "wave"}],
                         ids=["uniform", "ramped-curl", "alternating-wave"])
@pytest.mark.parametrize("elevation", [5.0, 35.0, 80.0])
def test_twisted_piece_windows_keep_exact_equal_to_brute(renderer, monkeypatch, shape, elevation):
    import app.render.renderer as renderer_module

    p, scene, cam = setup(renderer, {**TWISTED_WINDOW, **shape}, {"elevation": elevation})
    exact = renderer.render(p, cam, SIZE, outputs=("ids", "cost"), mode="exact")
    brute = renderer.render(p, cam, SIZE, outputs=("ids",), mode="brute")
    # the box alone (it takes the few pieces where the twist's rate meets the ray's: here every one)
    defines = renderer_module.model_defines
    monkeypatch.setattr(renderer_module, "model_defines",
                        lambda *a, **k: {**defines(*a, **k), "SHAPED_TURNED_WINDOW": 0})
    box = renderer.render(p, cam, SIZE, outputs=("ids", "cost"), mode="exact")
    assert exact.hit.sum() > 300
    for name, frame in (("turned", exact), ("box", box)):
        differ = np.any(frame.ids[..., :3] != brute.ids[..., :3], -1).sum()
        assert differ == 0, f"{name} windows, elevation {elevation}: {differ} pixels differ"
        assert frame.cost[..., 3].max() < 65_535
    covered = exact.cost[..., 2] > 0
    assert exact.cost[..., 0][covered].sum() <= box.cost[..., 0][covered].sum()


# Where the twist's rate meets the ray's own sweep about the axis, the angle in the twist's frame turns back
# along a piece, and its ends no longer bound it: those pieces take the box. Few do (the shapes bench's
# scene at eight turns: one or two pixels in 50,000 change without the check).
@pytest.mark.parametrize("pattern", ["uniform", "alternating"])
def test_pieces_where_the_twist_meets_the_rays_sweep_take_the_box(renderer, pattern):
    from app.bench.timing import UNFILTERED
    from app.scene.generators import build_scene

    p = Params({"scene.count": 8, "shape.twist": 8.0, "shape.twist_pattern": pattern, **UNFILTERED})
    scene = build_scene(p)
    renderer.set_scene(scene)
    cam = Camera.from_params(p, scene)
    exact = renderer.render(p, cam, (640, 360), outputs=("ids",), mode="exact")
    brute = renderer.render(p, cam, (640, 360), outputs=("ids",), mode="brute")
    assert exact.hit.sum() > 40_000
    differ = np.any(exact.ids[..., :3] != brute.ids[..., :3], -1).sum()
    assert differ == 0, f"{differ} pixels differ"


def test_a_rest_chord_keeps_its_angle_in_the_interpolated_twist_frame():
    # piece_window's epsF: the chord from E0 e^{i tau0} to E1 e^{i tau1}, at parameter t and turned back by
    # tau0 + t dTau, points within (pi / 2) x of the rest angle, x = (0.02 |dTau|^3 eMax + |E1 - E0| |dTau|
    # / 4) / (eMin cos(dTau / 2)), for |dTau| <= 1.5 and x small (the shader asks epsF <= 0.08)
    rng = np.random.default_rng(7)
    d = rng.uniform(-1.5, 1.5, 20000)
    e0, e1 = rng.uniform(0.25, 1.0, (2, 20000))
    e1 = np.where(rng.random(20000) < 0.5, e0, e1)      # half without the ellipsoid
    t = np.linspace(0.0, 1.0, 101)[:, None]
    w = (1 - t) * e0 * np.exp(-1j * t * d) + t * e1 * np.exp(1j * (1 - t) * d)
    angle = np.abs(np.angle(w)).max(0)
    x = (0.02 * np.abs(d) ** 3 * np.maximum(e0, e1) + np.abs(e1 - e0) * 0.25 * np.abs(d)) / (
        np.minimum(e0, e1) * np.cos(d / 2))
    small = 1.5708 * x <= 0.08
    assert small.sum() > 5000
    assert np.all(angle[small] <= 1.5708 * x[small] + 1e-12)
    # and the bound is not slack by orders of magnitude: the twist's term alone is met within 2x
    same = small & (e0 == e1) & (np.abs(d) > 0.5)
    assert np.all(angle[same] <= 1.5708 * x[same]) and np.max(angle[same] / (1.5708 * x[same])) > 0.3


# The length screen (shaped.glsl: SHAPED_SCREEN) passes over fibers that end below a whole chord piece:
# long length jitter, curled fibers, seen across the tips and from above them.
SCREEN = {**POINT_STOP, "fibers.length_jitter": 0.7, "shape.curl_amplitude": 0.4, "shape.curl_frequency": 6.0}


@pytest.mark.parametrize("elevation", [10.0, 60.0])
def test_the_length_screen_keeps_every_fiber_and_saves_tests(renderer, monkeypatch, elevation):
    import app.render.renderer as renderer_module

    p, scene, cam = setup(renderer, SCREEN, {"elevation": elevation})
    screened = renderer.render(p, cam, SIZE, outputs=("ids", "cost"), mode="exact")
    brute = renderer.render(p, cam, SIZE, outputs=("ids",), mode="brute")
    defines = renderer_module.model_defines
    monkeypatch.setattr(renderer_module, "model_defines", lambda *a, **k: {**defines(*a, **k), "SHAPED_SCREEN": 0})
    plain = renderer.render(p, cam, SIZE, outputs=("ids", "cost"), mode="exact")
    assert screened.hit.sum() > 300
    differ = np.any(screened.ids[..., :3] != brute.ids[..., :3], -1).sum()
    assert differ == 0, f"elevation {elevation}: {differ} pixels differ from brute force"
    assert (plain.ids == screened.ids).all()
    covered = screened.cost[..., 2] > 0
    tests, unscreened = screened.cost[..., 0][covered].sum(), plain.cost[..., 0][covered].sum()
    assert tests < 0.8 * unscreened, f"the screen left {tests} of {unscreened} fiber tests"
    assert screened.cost[..., 3].max() < 65_535


# The screen must cut a fiber only where piece_entry does: a fiber that reaches its segment's end v1 goes
# on into the joint's wedge, where the ray's height passes v1 (bent joints, the tip's jitter range).
WEDGE = {"scene.generator": "single", "scene.radius": 1.0, "scene.length": 4.0, "scene.segments": 4,
         "scene.bend": 50.0, "fibers.rings": 4, "fibers.phi_step": 6.0, "fibers.fiber_radius": 0.1,
         "fibers.length_jitter": 0.7, "shape.curl_amplitude": 0.5, "shape.curl_frequency": 5.0,
         "shape.curl_pattern": "wave"}


@pytest.mark.parametrize("visibility", ["proxies", "walk"])
def test_the_length_screen_keeps_fibers_that_run_on_into_a_joint(renderer, visibility):
    p, scene, cam = setup(renderer, {**WEDGE, "quality.visibility": visibility}, {"elevation": 50.0})
    exact = renderer.render(p, cam, SIZE, outputs=("ids",), mode="exact")
    brute = renderer.render(p, cam, SIZE, outputs=("ids",), mode="brute")
    assert exact.hit.sum() > 1000
    differ = np.any(exact.ids[..., :3] != brute.ids[..., :3], -1).sum()
    assert differ == 0, f"{differ} pixels differ from brute force"


# A ray that starts inside fibers of two rings (camera inside the container, thick curled fibers that
# overlap) enters both at its start: the same s, so the lower ring wins as in brute force. Arcs that start
# at the same s (second halves and backs from the ray's start) must all be visited: the arc loop stops only
# at an arc that starts beyond the nearest hit (main's stopped at one starting at it, and lost such ties).
INSIDE = {"scene.generator": "single", "scene.radius": 1.0, "scene.length": 4.0, "fibers.rings": 4,
          "fibers.phi_step": 6.0, "fibers.fiber_radius": 0.12, "shape.curl_amplitude": 0.5,
          "shape.curl_frequency": 3.0, "fibers.length_jitter": 0.0, "quality.visibility": "proxies"}


@pytest.mark.parametrize("eye, target", [((-0.36, 0.66, 2.0), (0.24, 0.7, 1.71)),
                                         ((-0.51, -0.09, 2.0), (-0.4, -1.32, 1.32))])
def test_rays_starting_inside_fibers_break_ties_as_brute_force(renderer, eye, target):
    p = Params(INSIDE)
    from app.scene.generators import build_scene

    renderer.set_scene(build_scene(p))
    cam = Camera(list(eye), list(target), 70, 1e-3, 100)
    exact = renderer.render(p, cam, (96, 72), outputs=("ids",), mode="exact")
    brute = renderer.render(p, cam, (96, 72), outputs=("ids",), mode="brute")
    assert exact.hit.all()
    differ = np.any(exact.ids[..., :3] != brute.ids[..., :3], -1).sum()
    assert differ == 0, f"{differ} pixels differ from brute force"


def test_curved_glsl_matches_float64_reference(renderer):
    assert_matches_reference(renderer, [(values, {"elevation": 25.0}) for values in SHAPES.values()]
                             + [(SCREEN, {"elevation": 60.0})])


def test_twisted_fibers_have_twisted_tangents(renderer):
    # Kajiya-Kay shades by the tangent alone, so a twisted tangent shows as a changed colour
    straight = setup(renderer, ONE, {"elevation": 0.0})
    twisted = setup(renderer, {**ONE, "shape.twist": 1.0}, {"elevation": 0.0})
    frame_t = renderer.render(twisted[0], twisted[2], SIZE, outputs=("color", "ids"))
    base = renderer.render(straight[0], straight[2], SIZE, outputs=("color",))
    assert np.any(frame_t.color != base.color, -1).mean() > 0.02


AXES = [np.array(a, float) for a in
        ([1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1])]


@pytest.mark.parametrize("axis", AXES, ids=["+x", "-x", "+y", "-y", "+z", "-z"])
def test_frames_never_jump_near_the_axes(axis):
    x = orthonormal_x(axis)[0]
    assert abs(np.dot(x, axis)) < 1e-12 and abs(np.linalg.norm(x) - 1) < 1e-12
    for k in range(3):
        for eps in (1e-7, -1e-7):
            tilted = axis.copy()
            tilted[k] += eps
            tilted /= np.linalg.norm(tilted)
            assert np.linalg.norm(orthonormal_x(tilted)[0] - x) < 1e-5


@pytest.mark.parametrize("axis", AXES, ids=["+x", "-x", "+y", "-y", "+z", "-z"])
def test_axis_aligned_containers_render_the_same_pattern_as_tilted_ones(renderer, axis):
    """A container exactly along an axis and one tilted 1e-7 rad from it, each seen from the same side:
    same fibers, no NaN."""
    p = Params({**ONE, "fibers.phi_step": 6.0})
    images = []
    for tilt in (0.0, 1e-7):
        d = axis.copy()
        d[(np.argmax(np.abs(axis)) + 1) % 3] += tilt
        d /= np.linalg.norm(d)
        scene = Scene.from_polylines([np.array([-2 * d, 2 * d])], 1.0)
        renderer.set_scene(scene)
        side = np.cross(d, orthonormal_x(d)[0])
        cam = Camera(9.0 * side + 0.3 * d, np.zeros(3), 35.0, 0.5, 30.0, up=d)
        frame = renderer.render(p, cam, (96, 96), outputs=("ids", "geom"))
        assert np.isfinite(frame.geom).all()
        images.append(frame.ids[..., :3])
    assert (images[0][..., 0] > 0).sum() > 1000
    same = np.all(images[0] == images[1], -1).mean()
    assert same > 0.995, f"the pattern jumped: only {same:.3%} of pixels agree"


@pytest.mark.parametrize("bend", [0.0, 1.0, 30.0, 90.0])
def test_fibers_continue_across_joints(bend):
    """float64: a fiber's centre line meets itself on the joint plane (offset under 1e-4 R)."""
    a = np.radians(bend)
    guide = np.array([[0, 0, 0], [0, 0, 1.0], [np.sin(a), 0, 1 + np.cos(a)]])
    scene = Scene.from_polylines([guide], 0.2, origin=np.zeros(3))
    s0, s1 = (reference.segment(r) for r in scene.segments.astype(np.float64))
    p = Params({"fibers.rings": 4, "fibers.phi_step": 30.0, "fibers.fiber_radius": 0.05})
    lay = reference.ring_layout(p)
    _, _, cx, cy, _ = reference.all_fibers(lay, 0)
    joint = s0.p0 + s0.h * s0.ez
    n = s0.ez @ np.stack([s0.ex, s0.ey, s0.ez]).T @ np.stack([s0.ex, s0.ey, s0.ez])  # world axis
    n_joint = np.stack([s0.ex, s0.ey, s0.ez]).T @ s0.n1                              # joint normal
    for x, y in zip(cx, cy):
        ends = []
        for seg in (s0, s1):
            off = seg.r0 * (x * seg.ex + y * seg.ey)
            p0 = seg.p0 + off
            # where the fiber's line crosses the joint plane
            t = np.dot(joint - p0, n_joint) / np.dot(seg.ez, n_joint)
            ends.append(p0 + t * seg.ez)
        assert np.linalg.norm(ends[0] - ends[1]) < 1e-4 * 0.2, (bend, x, y)
    assert np.allclose(n, s0.ez)


@pytest.mark.parametrize("bend", [1.0, 30.0, 90.0])
def test_no_gap_and_no_double_hit_at_joints(renderer, bend):
    """A dense bent guide seen from the side: no background pixel along the joint inside the silhouette
    of the straight part, and exact still equals brute (a double hit would make them differ)."""
    values = {"scene.generator": "single", "scene.radius": 0.5, "scene.length": 4.0, "scene.segments": 2,
              "scene.bend": bend, "fibers.fiber_radius": 0.05, "fibers.phi_step": 2.0,
              "fibers.length_jitter": 0.0, "fibers.rings": 10}
    p, scene, cam = setup(renderer, values, {"azimuth": 90.0, "elevation": 0.0})
    exact = renderer.render(p, cam, SIZE, outputs=("ids",), mode="exact")
    brute = renderer.render(p, cam, SIZE, outputs=("ids",), mode="brute")
    assert (exact.ids[..., :3] == brute.ids[..., :3]).all()
    # rows through the joint region: coverage has no hole in the middle of each covered run
    hit = exact.hit
    rows = np.nonzero(hit.any(1))[0]
    for r in rows[len(rows) // 3: 2 * len(rows) // 3]:
        cols = np.nonzero(hit[r])[0]
        assert cols.max() - cols.min() + 1 - len(cols) <= 1, f"gap in row {r} at bend {bend}"
