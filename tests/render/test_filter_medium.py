"""The filtered mode's medium (glsl/fibers/coverage.glsl: ring_fence .. cover_medium): a container whose
fibers are far below the footprint is shaded as a medium. Its closed forms against numeric integration, its
coverage against the fibers' own geometry, the GLSL against the numpy twins value by value, the constants
both sides share, and the blend from the scan into the medium as a camera dollies out (no step)."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from app import fibers, reference
from app.gl.shaders import glsl_root
from app.presets import find_preset
from app.render.camera import Camera
from app.scene.generators import build_scene
from tests.support.glsl_harness import run_fragment

SIZE = (160, 90)
ON = {"quality.filter": "coverage"}
COVERAGE_GLSL = glsl_root() / "fibers" / "coverage.glsl"


def test_constants_are_the_shaders():
    text = COVERAGE_GLSL.read_text()
    for name in ("COVER_OPAQUE", "COVER_MEDIUM_FROM", "COVER_MEDIUM_FULL", "COVER_TENT_MIN", "COVER_LIGHT_NODES"):
        m = re.search(rf"#define {name} ([0-9.eE+-]+)", text)
        assert m, f"coverage.glsl defines no {name}"
        assert float(m.group(1)) == getattr(reference, name), name


# --- the fence against numeric integration ------------------------------------------------------------------
def _tent_integral(f, d, w, n=40001):
    """The trapezoid rule of the tent (half-width w, area 1) against g over [d - w, d + w]."""
    x = np.linspace(d - w, d + w, n)
    y = (1.0 - np.abs(x - d) / w) / w * reference.ring_fence_g(f, x)
    return float(((y[1:] + y[:-1]) / 2).sum() * (x[1] - x[0]))


@pytest.mark.parametrize("rho, n, rf", [(0.95, 360, 0.01), (0.833, 24, 0.1), (0.5, 40, 0.004), (0.2, 6, 0.01)],
                         ids=["closed-dense", "fur-ball-open", "open-sparse", "inner-sparse"])
def test_fence_cover_is_the_tent_integral_of_g(rho, n, rf):
    """ring_fence_cover (the tent's second difference of g's second antiderivative) against the trapezoid
    rule of the tent against g itself, across the ring, at its tangent and past it, narrow and wide."""
    f = reference.ring_fence(rho, n, rf)
    rng = np.random.default_rng(16)
    d = np.concatenate([rng.uniform(0, 1.5 * rho, 40), [0.0, rho, rho * 0.999, f.ys]])
    w = np.concatenate([rng.uniform(0.05 * rho, 3.0 * rho, 40), [0.3 * rho] * 4])
    got = reference.ring_fence_cover(f, d, w)
    want = np.array([_tent_integral(f, di, wi) for di, wi in zip(d, w)])
    # g has an integrable 1/sqrt peak at the tangent of an open fence: the trapezoid rule converges slowly
    assert np.allclose(got, want, atol=3e-3), np.abs(got - want).max()
    # the mean over the ring's width is g's integral over it
    u = np.linspace(0, rho, 200001)
    g = reference.ring_fence_g(f, u[:-1] + 0.5 * (u[1] - u[0]))
    assert reference.ring_fence_mean(f) == pytest.approx(g.mean(), abs=2e-3)
    # a line footprint is g itself; a closed fence covers a footprint inside it whole
    assert reference.ring_fence_cover(f, 0.3 * rho, 1e-4 * rho) == pytest.approx(
        float(reference.ring_fence_g(f, 0.3 * rho)), rel=1e-9)
    if f.ys == 0.0:
        assert reference.ring_fence_cover(f, 0.2 * rho, 0.5 * rho) == pytest.approx(1.0, abs=1e-9)


def _true_alpha(lay, guide, d, w, theta, nx=3001):
    """The tent-weighted share of a footprint the union of a container's fibers covers, looking along
    direction theta in its cross-section (fibers as straight vertical cylinders)."""
    ring, _, cx, cy, _ = fibers.all_fibers(lay, guide)
    rf = lay.ring_radius[ring]
    across = -cx * math.sin(theta) + cy * math.cos(theta)
    u = np.linspace(-1.0, 1.0, nx)
    x = d + w * u
    hit = (np.abs(x[:, None] - across[None, :]) < rf[None, :]).any(1)
    tent = 1.0 - np.abs(u)
    return float((tent * hit).sum() / tent.sum())


@pytest.mark.parametrize("preset, w", [("default", 0.26), ("default", 2.5), ("fur-ball", 0.67)],
                         ids=["dense-footprint-inside", "dense-footprint-wider-than-it", "fur-ball-far"])
def test_medium_alpha_follows_the_fibers(preset, w):
    """The medium's coverage against the actual fibers' coverage, averaged over containers and view
    directions, at offsets across the container: within a few percent of the footprint. The rescale at
    COVER_OPAQUE is taken off both (the medium's alpha reaches 1 where COVER_OPAQUE (6%) still shows through)."""
    lay = fibers.ring_layout(find_preset(preset).params)
    rng = np.random.default_rng(7)
    ds = np.linspace(0.0, 1.0 + w, 9)
    truth = np.zeros(len(ds))
    for g in range(6):
        theta = rng.uniform(0, 2 * math.pi)
        truth += [_true_alpha(lay, g, d, w, theta) for d in ds]
    truth /= 6
    truth = 1.0 - np.maximum((1.0 - truth) - reference.COVER_OPAQUE, 0.0) / (1.0 - reference.COVER_OPAQUE)
    model = reference.medium_alpha(lay, ds, w)
    assert np.abs(model - truth).max() < 0.08, np.c_[ds, truth, model]
    assert np.abs(model - truth).mean() < 0.04, np.c_[ds, truth, model]


def test_medium_hides_inner_rings_behind_closed_fences():
    """Nested rings: a footprint wider than a dense container sees its outer ring's silhouette, not the
    outer ring's coverage plus the inner rings' through it (what compositing shares of the whole footprint
    would give: too much coverage, drawn from too deep)."""
    lay = fibers.ring_layout(find_preset("default").params)
    w = 3.0
    outer = reference.ring_fence(float(lay.rho[0] + lay.ring_radius[0]), float(lay.n[0]), float(lay.ring_radius[0]))
    alone = 1.0 - (1.0 - float(reference.ring_fence_cover(outer, 0.0, w))) ** 2    # both arcs, as shares
    shares = np.array([float(reference.ring_fence_cover(
        reference.ring_fence(float(r + rf), float(n), float(rf)), 0.0, w)) for r, n, rf in
        zip(lay.rho, lay.n, lay.ring_radius)])
    independent = 1.0 - np.prod((1.0 - shares) ** 2)
    got = float(reference.medium_alpha(lay, 0.0, w)) * (1 - reference.COVER_OPAQUE)
    assert got == pytest.approx(float(reference.ring_fence_cover(outer, 0.0, w)), abs=1e-9)
    assert independent > alone > got - 1e-9


def test_medium_weight_and_exp_mean():
    n, k = 3600, 10
    slot = math.pi / (n / k)                             # a mean ring's slot, halfway out: pi / (n / k) ...
    assert reference.medium_weight(0.5 * 11.0 * slot, n, k) == 0.0      # ... so wu = slots / 2 * slot
    assert reference.medium_weight(0.5 * 21.0 * slot, n, k) == 1.0
    slots = np.linspace(0, 30, 601)
    b = reference.medium_weight(0.5 * slots * slot, n, k)
    assert (np.diff(b) >= 0).all() and np.abs(np.diff(b)).max() < 0.01, "smooth, rising"
    # exp_mean: the mean of exp over a linear path, against the trapezoid rule; the limits
    p = np.linspace(0.2, 1.7, 100001)
    assert reference.exp_mean(5.0, 0.2, 1.7) == pytest.approx(np.exp(-5.0 * p).mean(), rel=1e-4)
    assert reference.exp_mean(5.0, 0.4, 0.4) == pytest.approx(math.exp(-2.0))
    assert reference.exp_mean(0.0, 0.1, 3.0) == 1.0


HARNESS = """#version 450 core
#include "fibers/coverage.glsl"
uniform float uRho;
uniform float uN;
uniform float uRf;
uniform float uFrom;
layout(location = 0) out vec4 outValue;
void main() {
    vec2 q = gl_FragCoord.xy - 0.5;
    float d = q.x / 40.0;                          // 0 .. 1.6
    float w = exp2(q.y / 8.0 - 5.0) * uFrom;       // 1/32 .. 8 times where the medium starts
    Fence f = ring_fence(uRho, uN, uRf);
    float p1 = 0.1 + d;
    float e0 = exp(-4.0 * 0.1), e1 = exp(-4.0 * p1);
    outValue = vec4(ring_fence_cover(f, d, w), ring_fence_mean(f), medium_weight(w, uN, uRings),
                    exp_mean(4.0, 0.1, p1, e0, e1));
}
"""


@pytest.mark.parametrize("rho, n, rf", [(0.95, 360, 0.01), (0.833, 24, 0.1), (0.5, 40, 0.004)],
                         ids=["closed", "fur-ball", "open"])
def test_glsl_medium_matches_numpy(ctx, rho, n, rf):
    # the footprint where the medium starts to blend in (medium_weight): COVER_MEDIUM_FROM slots of a
    # container of n fibers in 4 rings
    start = 0.5 * reference.COVER_MEDIUM_FROM * math.pi / (n / 4)

    def setup(prog):
        prog["uRho"].value, prog["uN"].value, prog["uRf"].value = rho, n, rf
        prog["uFrom"].value = start
        prog["uRings"].value = 4

    W, H = 64, 64
    v = run_fragment(ctx, HARNESS, (W, H), setup)
    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    d, w = x / 40.0, np.exp2(y / 8.0 - 5.0) * start
    f = reference.ring_fence(rho, n, rf)
    assert np.isfinite(v).all()
    # float32 second differences: where the footprint is narrow against the ring they lose digits; from
    # where the medium starts on (w >= start, row 40 on) a few 1e-4 of the footprint
    err = np.abs(v[..., 0] - reference.ring_fence_cover(f, d, w))
    assert err[40:].max() < 1e-3, err[40:].max()
    assert err.max() < 5e-2, err.max()          # below it (never used there): no blow-up
    assert np.allclose(v[..., 1], reference.ring_fence_mean(f), atol=5e-4)      # llvmpipe asin: ~1e-4
    assert np.allclose(v[..., 2], reference.medium_weight(w, n, 4), atol=1e-5)
    assert np.allclose(v[..., 3], reference.exp_mean(4.0, 0.1, 0.1 + d), rtol=2e-4, atol=1e-6)


# --- the blend from the scan into the medium: no step where one becomes the other ---------------------------
def _footprint_wu(p, scene, cam):
    """The filter's footprint half-width in container radii at the scene's centre."""
    dist = float(np.linalg.norm(np.asarray(cam.position, np.float64) - np.asarray(cam.target, np.float64)))
    pixel = 2.0 * math.tan(math.radians(cam.fov) / 2) / SIZE[1]
    return p["quality.filter_width"] * pixel * dist / float(np.median(scene.segments[:, 3]))


def test_widening_footprint_crosses_the_switch_without_a_step(renderer):
    """One container (the straight preset with 72 fibers a ring: all of them switch together), camera still,
    the footprint widened from under COVER_MEDIUM_FROM fiber slots to past COVER_MEDIUM_FULL in 60 steps:
    the picture blurs step by step, and no step changes it much more than the steps beside it. A switch
    from the scan to the medium at one width measured a step of 11.6 levels, 15 times its neighbours'; this
    blend 2.9 and 4.9 times, where the scan alone steps as much (3.1, 4.9: its thinning doubling)."""
    p = find_preset("straight").params.replace(**{"quality.supersample": 1, "quality.msaa": 0,
                                                   "camera.distance": 10.0, "fibers.phi_step": 5.0, **ON})
    scene = build_scene(p)
    renderer.set_scene(scene)
    cam = Camera.from_params(p, scene, aspect=SIZE[0] / SIZE[1])
    lay = fibers.ring_layout(p)
    n, k = lay.fibers_per_container, lay.rings
    widths = np.geomspace(0.25, 4.0, 60)
    for width, weight in ((0.25, 0.0), (4.0, 1.0)):
        wu = _footprint_wu(p.replace(**{"quality.filter_width": width}), scene, cam)
        assert reference.medium_weight(wu, n, k) == weight
    steps, prev = [], None
    for w in widths:
        f = renderer.render(p.replace(**{"quality.filter_width": float(w)}), cam, SIZE, outputs=("color",))
        c = f.color.astype(np.float64)
        if prev is not None:
            covered = (f.coverage > 0) | (prev[1] > 0)
            steps.append(np.abs(c - prev[0]).max(-1)[covered].mean())
        prev = (c, f.coverage)
    steps = np.array(steps)
    beside = np.array([np.median(np.delete(steps[max(0, k - 3):k + 4], min(k, 3))) for k in range(len(steps))])
    assert steps.max() < 6.0, np.round(steps, 2)
    assert (steps / np.maximum(beside, 1e-3)).max() < 8.0, np.round(steps, 2)


def test_cover_light_path_reaches_the_wall():
    rng = np.random.default_rng(3)
    r = np.sqrt(rng.uniform(0, 1, 500))
    a = rng.uniform(0, 2 * math.pi, 500)
    q = np.stack([r * np.cos(a), r * np.sin(a)], -1)
    b = rng.uniform(0, 2 * math.pi, 500)
    tilt = rng.uniform(0.05, 1.0, 500)                  # the light's xy part: shorter the steeper it climbs
    l2 = np.stack([tilt * np.cos(b), tilt * np.sin(b)], -1)
    t = reference.cover_light_path(q, l2)
    assert (t >= 0).all()
    assert np.allclose(np.linalg.norm(q + t[:, None] * l2, axis=-1), 1.0, atol=1e-9)
    assert reference.cover_light_path(np.array([0.3, 0.0]), np.array([0.0, 0.0])) == np.inf


# --- the medium's key light against the fibers' geometry ------------------------------------------------------
def _first_hit_light(lay, guide, theta, l2, sigma, ys):
    """Per ray across a container's cross-section (direction theta, offsets ys): the density-estimate
    transmittance at the first fiber it meets, as the unfiltered frame shades it (NaN where it meets none).
    Fibers as straight vertical cylinders."""
    ring, _, cx, cy, _ = fibers.all_fibers(lay, guide)
    rf = lay.ring_radius[ring]
    dv = np.array([math.cos(theta), math.sin(theta)])
    nv = np.array([-dv[1], dv[0]])
    off = ys[:, None] - (cx * nv[0] + cy * nv[1])[None]
    along = (cx * dv[0] + cy * dv[1])[None]
    t = np.where(np.abs(off) < rf[None], along - np.sqrt(np.maximum(rf[None] ** 2 - off ** 2, 0)), np.inf)
    t = t.min(1)
    hit = np.where(np.isfinite(t)[:, None], t[:, None] * dv + ys[:, None] * nv, 0.0)
    e = np.exp(-sigma * np.maximum(reference.cover_light_path(hit, l2), 0.0))
    return np.where(np.isfinite(t), e, np.nan)


def _auto_layout(name):
    from app.presets import resolve_params
    from tests.support.paths import HAIR_DATA

    path = HAIR_DATA / name
    if not path.exists():
        pytest.skip(f"shared hair data not found at {path}")
    return resolve_params(str(path), [])[0]


@pytest.mark.parametrize("subject", ["default", "harolongo.data"])
def test_medium_light_follows_the_fibers(subject):
    """The medium's key light on its outer ring (the only one a footprint sees through these closed
    fences), held to the light at the fibers a ray meets first, over view and light directions and footprints
    at the centre, halfway out and near the edge. groom_auto lays harolongo's outer ring 6.8 fibers deep
    (80 fibers of 0.2 radii on a ring of 0.75) under a density of 8 a radius: the medium took the light on
    the ring's own radius, 47% darker than those fibers' (0.13 against 0.25 here), and the filtered frame
    came out 19 levels too dark (docs/antialias.md). The default preset's outer ring reads 13% dark before
    and after: its fibers (k = 1.2 widths a point of the ring) are staggered by a radial jitter of twice their
    radius, and a ray often meets one in front of the ring, which q (0.1 there) does not see."""
    from app.render import look

    p = find_preset("default").params if subject == "default" else _auto_layout(subject)
    lay = fibers.ring_layout(p)
    sigma = p["look.shadow_density"] * look.fiber_density(p, lay.fibers_per_container)
    assert reference.ring_fence_mean(reference.ring_fence(float(lay.rho[0] + lay.ring_radius[0]), float(lay.n[0]),
                                                          float(lay.ring_radius[0]))) > 0.999
    rng = np.random.default_rng(5)
    ys = np.linspace(-1.0, 1.0, 1601)
    truth, model = [], []
    for g in range(32):
        theta, la, tilt = rng.uniform(0, 2 * math.pi), rng.uniform(0, 2 * math.pi), rng.uniform(0.3, 1.0)
        l2 = tilt * np.array([math.cos(la), math.sin(la)])
        e = _first_hit_light(lay, g % 8, theta, l2, sigma, ys)
        l2v = np.array([l2 @ [math.cos(theta), math.sin(theta)], l2 @ [-math.sin(theta), math.cos(theta)]])
        for d, w in ((0.0, 0.2), (0.5, 0.2), (0.85, 0.2), (0.0, 5.0)):
            sel = (np.abs(ys - d) < 0.70710678 * w) & np.isfinite(e)
            truth.append(float(e[sel].mean()))
            model.append(float(reference.medium_arc_light(lay, 0, d, w, l2v, sigma)[0]))
    truth, model = np.array(truth), np.array(model)
    assert abs((model - truth).mean()) < 0.15 * truth.mean(), (model.mean(), truth.mean())
    assert np.abs(model - truth).mean() < 0.25 * truth.mean(), (np.abs(model - truth).mean(), truth.mean())


FACE_HARNESS = """#version 450 core
#include "fibers/coverage.glsl"
layout(location = 0) out vec4 outValue;
void main() {
    vec2 q = gl_FragCoord.xy - 0.5;
    float rho = 0.05 + 0.9 * q.x / 15.0;
    float n = exp2(q.y / 2.0);                    // 1 .. 256 fibers
    outValue = vec4(medium_face(rho, n, 0.02 + 0.1 * fract(q.x * 0.37), 0.03), 0.0);
}
"""


def test_glsl_medium_face_matches_numpy(ctx):
    W, H = 16, 17
    v = run_fragment(ctx, FACE_HARNESS, (W, H))
    for y in range(H):
        for x in range(W):
            want = reference.medium_face(0.05 + 0.9 * x / 15.0, 2.0 ** (y / 2.0), 0.02 + 0.1 * ((x * 0.37) % 1.0), 0.03)
            assert np.allclose(v[y, x, :3], want, rtol=1e-5, atol=1e-6), (x, y, v[y, x], want)
