"""The shading tangent runs on across joints (glsl/shading/tangent.glsl): a container segment is straight,
its guide bends at every joint, and shading takes the guide's direction blended between the two joint
planes by where the point lies between them, and turns the normal with it. At a joint both segments give
one tangent and one normal (the rule before, a blend by height, stepped by degrees for fibers off the
axis and left the normal kinked with the straight fibers), for the virtual fibers and the explicit
baseline; ids do not move (shading only). docs/antialias.md, "Low roughness"."""

from __future__ import annotations

import hashlib
import math

import numpy as np
import pytest

from app import reference
from app.bench.highlights import height_blended_axis, joint_blended_axis, joint_excess, turn_with
from app.params import Params
from app.render.camera import Camera
from app.render.explicit import ExplicitRenderer
from app.scene.containers import container_rows
from app.scene.generators import build_scene
from tests.support.glsl_harness import run_fragment


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _bent_pair(bend_deg=40.0, radius=0.45):
    """Two unit-length segments of one guide meeting at ``bend_deg``, as reference.Segment, and their rows."""
    th = math.radians(bend_deg)
    guide = np.array([[[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [math.sin(th), 0.0, 1.0 + math.cos(th)]]])
    rows = container_rows(guide, np.array([radius]), 0.0, np.zeros(3))
    return reference.segment(rows[0]), reference.segment(rows[1]), rows


def _joint_points(a, radius, count=16):
    """World points on the joint plane at the container's wall, and each segment's surface normal there
    (perpendicular to its own axis: the straight fibers' sides)."""
    n = np.stack([a.ex, a.ey, a.ez]).T @ a.n1
    e1 = _unit(np.cross(n, [0.0, 1.0, 0.0]))
    e2 = np.cross(n, e1)
    ang = np.linspace(0.0, 2.0 * np.pi, count, endpoint=False)
    joint = a.p0 + a.h * a.ez
    return joint + radius * (np.cos(ang)[:, None] * e1 + np.sin(ang)[:, None] * e2), joint


def _frame(s):
    return np.stack([s.ex, s.ey, s.ez])


def test_tangent_and_normal_run_on_across_a_joint():
    """numpy twins: on the joint plane of a 40 degree bend both segments give one tangent and one turned
    normal; the height blend steps there and the straight fibers' own normals kink."""
    a, b, _ = _bent_pair()
    pts, joint = _joint_points(a, 0.45)
    ta = joint_blended_axis(a.n0, a.n1, a.h, (pts - a.p0) @ _frame(a).T) @ _frame(a)
    tb = joint_blended_axis(b.n0, b.n1, b.h, (pts - b.p0) @ _frame(b).T) @ _frame(b)
    step = np.degrees(np.arccos(np.clip(np.sum(ta * tb, -1), -1, 1)))
    assert step.max() < 1e-4, step
    old_a = height_blended_axis(a.n0, a.n1, a.h, (pts - a.p0) @ _frame(a).T) @ _frame(a)
    old_b = height_blended_axis(b.n0, b.n1, b.h, (pts - b.p0) @ _frame(b).T) @ _frame(b)
    old_step = np.degrees(np.arccos(np.clip(np.sum(old_a * old_b, -1), -1, 1)))
    assert old_step.max() > 3.0, "the height blend should step at this joint (the test could not fail)"
    # the fibers' sides: radial from each segment's own axis
    na = _unit((pts - joint) - np.outer((pts - joint) @ a.ez, a.ez))
    nb = _unit((pts - joint) - np.outer((pts - joint) @ b.ez, b.ez))
    kink = np.degrees(np.arccos(np.clip(np.sum(na * nb, -1), -1, 1)))
    assert kink.max() > 20.0
    sa = turn_with(na, np.broadcast_to(a.ez, na.shape), ta)
    sb = turn_with(nb, np.broadcast_to(b.ez, nb.shape), tb)
    assert np.allclose(sa, sb, atol=1e-6), np.abs(sa - sb).max()
    assert np.allclose(np.sum(sa * ta, -1), 0.0, atol=1e-6), "the turned normal is perpendicular to T"


HARNESS = """#version 450 core
#include "shading/tangent.glsl"
uniform vec3 uN0;
uniform vec3 uN1;
uniform float uH;
uniform vec3 uPoint[16];
uniform vec3 uNormal[16];
uniform vec3 uFiber;
layout(location = 0) out vec4 outValue;
void main() {
    int i = int(gl_FragCoord.x);
    vec3 T = joint_blended_axis(uN0, uN1, uH, uPoint[i]);
    outValue = gl_FragCoord.y < 1.0 ? vec4(T, 0.0) : vec4(turn_with(uNormal[i], uFiber, T), 0.0);
}
"""


def _glsl(ctx, seg, points, normals):
    def setup(prog):
        prog["uN0"].value, prog["uN1"].value, prog["uH"].value = tuple(seg.n0), tuple(seg.n1), seg.h
        prog["uPoint"].write(np.asarray(points, np.float32).tobytes())
        prog["uNormal"].write(np.asarray(normals, np.float32).tobytes())
        prog["uFiber"].value = (0.0, 0.0, 1.0)

    v = run_fragment(ctx, HARNESS, (len(points), 2), setup)[..., :3]
    return v[0], v[1]


def test_glsl_tangent_is_its_numpy_twin_and_continuous(ctx):
    a, b, _ = _bent_pair()
    pts, joint = _joint_points(a, 0.45)
    out = {}
    for name, s in (("a", a), ("b", b)):
        local = (pts - s.p0) @ _frame(s).T
        radial = (pts - joint) @ _frame(s).T
        normal = _unit(radial * np.array([1.0, 1.0, 0.0]))     # the side of a fiber along this segment
        t, n = _glsl(ctx, s, local, normal)
        want_t = joint_blended_axis(s.n0, s.n1, s.h, local)
        assert np.allclose(t, want_t, atol=2e-6), np.abs(t - want_t).max()
        assert np.allclose(n, turn_with(normal, np.broadcast_to([0.0, 0.0, 1.0], normal.shape), want_t), atol=2e-6)
        out[name] = (t @ _frame(s), n @ _frame(s))
    assert np.allclose(out["a"][0], out["b"][0], atol=1e-5), "one tangent on the joint plane"
    assert np.allclose(out["a"][1], out["b"][1], atol=1e-5), "one shading normal on the joint plane"


# --- the density self-shadow's path runs on across a joint too (tangent.glsl: joint_light_path) ------------
LIGHT_HARNESS = """#version 450 core
#include "shading/tangent.glsl"
uniform vec3 uN0;
uniform vec3 uN1;
uniform float uH;
uniform vec2 uRadii;
uniform vec3 uPoint[16];
uniform vec3 uLight[4];
layout(location = 0) out vec4 outValue;
void main() {
    int i = int(gl_FragCoord.x);
    vec3 L = uLight[int(gl_FragCoord.y)];
    outValue = vec4(joint_light_path(uN0, uN1, vec3(0.0, 0.0, uH), uRadii, bvec2(false), uPoint[i], L), 0.0, 0.0, 0.0);
}
"""
LIGHTS = _unit(np.array([[0.3, 0.9, 0.2], [-0.8, 0.1, 0.5], [0.2, -0.6, -0.7], [0.9, 0.3, -0.1]]))


def _light_paths(ctx, seg, radii, local_points, local_lights):
    def setup(prog):
        prog["uN0"].value, prog["uN1"].value, prog["uH"].value = tuple(seg.n0), tuple(seg.n1), seg.h
        prog["uRadii"].value = tuple(radii)
        prog["uPoint"].write(np.asarray(local_points, np.float32).tobytes())
        prog["uLight"].write(np.asarray(local_lights, np.float32).tobytes())

    return run_fragment(ctx, LIGHT_HARNESS, (len(local_points), len(local_lights)), setup)[..., 0]


def _own_cylinder_path(local_point, local_light, radius):
    """The rule before: the path to the wall of the segment's own straight cylinder (|xy| = radius)."""
    q, d = local_point[:2], local_light[:2]
    a, b, c = d @ d, q @ d, q @ q - radius * radius
    return (-b + math.sqrt(max(b * b - a * c, 0.0))) / a / radius


def test_self_shadow_path_runs_on_across_a_joint(ctx):
    """Points inside the container on the joint plane of a 40 degree bend: from either segment the key
    light's path to the wall is one length (each segment's own cylinder gave another, the step that banded
    sintel's self-shadow at every joint: docs/antialias.md); on a straight guide it is the cylinder's."""
    a, b, rows = _bent_pair()
    radius = rows[0, 3]
    pts, _ = _joint_points(a, 0.6 * radius)
    paths, old = {}, {}
    for name, s in (("a", a), ("b", b)):
        local = (pts - s.p0) @ _frame(s).T
        lights = LIGHTS @ _frame(s).T
        paths[name] = _light_paths(ctx, s, (radius, radius), local, lights)
        old[name] = np.array([[_own_cylinder_path(p, L, radius) for p in local] for L in lights])
    assert np.all(np.isfinite(paths["a"])) and paths["a"].min() >= 0.0
    assert np.allclose(paths["a"], paths["b"], rtol=1e-4, atol=1e-5), np.abs(paths["a"] - paths["b"]).max()
    assert np.abs(old["a"] - old["b"]).max() > 0.1, "the old rule should step here: the scene lost its bend"
    # a straight guide: the blended cylinder is the segment's own
    straight, _, srows = _bent_pair(bend_deg=0.0)
    local = np.column_stack([0.6 * radius * np.cos(np.arange(16)), 0.6 * radius * np.sin(np.arange(16)),
                             np.linspace(0.05, 0.95, 16)])
    got = _light_paths(ctx, straight, (radius, radius), local, LIGHTS)
    want = np.array([[_own_cylinder_path(p, L, radius) for p in local] for L in LIGHTS])
    assert np.allclose(got, want, rtol=1e-4, atol=1e-5), np.abs(got - want).max()


# --- in the picture: a bent two-segment container with the key light mirrored about the joint's bisector
# (a Kajiya-Kay highlight right at the joint), 640x360, four sub-pixel offsets
SIZE = (640, 360)
OFFSETS = ((0.0, 0.0), (0.5, 0.0), (0.0, 0.5), (0.5, 0.5))
BENT = {"scene.generator": "single", "scene.radius": 0.35, "scene.length": 2.0, "scene.segments": 2,
        "scene.bend": 60.0, "fibers.rings": 6, "fibers.fiber_radius": 0.04, "look.model": "kajiya_kay",
        "look.roughness": 0.1, "look.self_shadow": "off", "camera.azimuth": 60.0, "camera.elevation": 10.0}
# sha256 of the virtual frame's ids at offset 0 on llvmpipe, recorded before the tangent changed
IDS_SHA = "b1cf26b7128264c8"


def _bent_scene():
    p = Params(BENT)
    scene = build_scene(p)
    cam = Camera.from_params(p, scene, aspect=SIZE[0] / SIZE[1])
    n = _unit(scene.segments[0, 12:15].astype(np.float64))
    view = _unit(np.asarray(cam.position, np.float64) - np.asarray(cam.target, np.float64))
    light = view - 2.0 * (view @ n) * n
    p = p.replace(**{"look.light_azimuth": math.degrees(math.atan2(light[1], light[0])),
                     "look.light_elevation": math.degrees(math.asin(light[2]))})
    return p, scene, cam


@pytest.mark.parametrize("method, bound", [("virtual", 10.0), ("explicit", 18.0)])
def test_a_highlight_runs_on_across_a_joint(gl, renderer, method, bound):
    """joint_excess: the share of one guide's pixel pairs across the joint whose luminance steps more than
    8 levels past the steps beside it. Measured (mean of the four offsets): virtual 3.6%, explicit 11%;
    with the height blend and unturned normals 27% and 32% (the explicit ribbons' square ends at the kink
    added seams too), so both fail these bounds."""
    p, scene, cam = _bent_scene()
    if method == "virtual":
        r = renderer
        r.set_scene(scene)
    else:
        r = ExplicitRenderer(gl.ctx)
        r.set_scene(scene, p)
    try:
        frames = [r.render(p, cam, SIZE, outputs=("color", "ids"), offset=o) for o in OFFSETS]
    finally:
        if method == "explicit":
            r.release()
            r.release_targets()
    shares = [joint_excess(f.color, f.ids) for f in frames]
    assert min(n for _, n in shares) > 100, "the joint should be seen"
    assert np.mean([s for s, _ in shares]) < bound, shares
    if method == "virtual" and "llvmpipe" in gl.renderer:     # the recorded ids are llvmpipe's
        sha = hashlib.sha256(frames[0].ids.tobytes()).hexdigest()[:16]
        assert sha == IDS_SHA, "shading must not move a fiber: the ids changed"
