"""GLSL library functions against their numpy twins, value by value (lygia's way of testing)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from app import reference
from app.gl.shaders import ProgramCache, glsl_root
from tests.support.paths import GLSL_HARNESS

W, H = 64, 32


@pytest.fixture(scope="module")
def values(ctx):
    # the harness lives in tests/, the library in glsl/: expand from a root that sees both
    import shutil
    import tempfile

    tmp = Path(tempfile.mkdtemp())
    shutil.copytree(glsl_root(), tmp / "glsl")
    for f in GLSL_HARNESS.iterdir():
        (tmp / "glsl" / f.name).write_text(f.read_text())
    prog = ProgramCache(tmp / "glsl").get(ctx, "fullscreen.vert", "functions.frag")
    prog["uSeed"].value = 1234
    prog["uRay"].value = (-1.0, 0.3, 1.0, -0.15)
    prog["uRadius"].value = 0.35
    hashes = ctx.texture((W, H), 4, dtype="u4")
    vals = ctx.texture((W, H), 4, dtype="f4")
    fbo = ctx.framebuffer([hashes, vals])
    fbo.use()
    ctx.viewport = (0, 0, W, H)
    ctx.disable(__import__("moderngl").CULL_FACE | __import__("moderngl").DEPTH_TEST)
    ctx.vertex_array(prog, []).render(vertices=3)
    h = np.frombuffer(hashes.read(), np.uint32).reshape(H, W, 4)
    v = np.frombuffer(vals.read(), np.float32).reshape(H, W, 4)
    # bind a live framebuffer before releasing ours: moderngl rebinds the current one whenever it creates
    # a framebuffer, and rebinding a released one leaves GL_INVALID_OPERATION for the next test
    ctx.framebuffer(ctx.renderbuffer((1, 1))).use()
    fbo.release()
    hashes.release()
    vals.release()
    shutil.rmtree(tmp)
    y, x = np.mgrid[0:H, 0:W].astype(np.uint32)
    return x, y, h, v


def test_integer_hash_is_bit_identical(values):
    x, y, h, v = values
    with np.errstate(over="ignore"):
        assert (h[..., 0] == reference.lowbias32(x * np.uint32(7919) + y)).all()
    key = reference.fiber_hash(1234, x, y, x ^ y, 0)  # fiber_hash hashes the channel too: compare keys
    want_key = reference.lowbias32(reference.lowbias32(reference.lowbias32(
        reference.lowbias32(np.uint32(1234) + np.uint32(0x9E3779B9)) ^ x) ^ y) ^ (x ^ y))
    assert (h[..., 1] == want_key).all()
    assert key.shape == want_key.shape


def test_fiber_random_is_identical(values):
    x, y, h, v = values
    want = reference.fiber_random(1234, x, y, x + y, 2)
    assert (v[..., 0].astype(np.float64) == want).all(), "24-bit randoms must match exactly"


def test_thesis_random_is_in_range_but_not_reproducible(values):
    """The thesis's fract(1207.523 * phi) in float32 is in [0, 1) but not reproducible: phi * 1207.5 is
    around 1e5, where a float32 step is ~0.01, so any rounding difference (fused multiply-add, the order
    of the sums) moves the result. The integer hash above is bit-exact; this is why it is the default.
    ``app.bench.quality`` reports the mismatch rate."""
    x, y, h, v = values
    got = v[..., 1].astype(np.float64)
    assert ((got >= 0) & (got < 1)).all()
    slot = (x.astype(np.float32) * np.float32(0.37) + y.astype(np.float32) * np.float32(3.1))
    want32 = reference.thesis_random(slot, (y % 7).astype(np.float32), 1.0, np.float32)
    assert (np.abs(got - want32) < 1e-3).mean() > 0.5   # most agree; the rest is the instability


def test_circle_interval_matches_float64(values):
    x, y, h, v = values
    ox = -1.0 + x.astype(np.float64) * 0.01
    oy = 0.3 + y.astype(np.float64) * 0.01
    t0, t1 = reference.circle_interval(ox, oy, 1.0, -0.15, 0.2, -0.1, 0.35)
    hit = np.isfinite(t0)
    got_hit = v[..., 2] <= v[..., 3]
    assert hit.sum() > 100
    assert (got_hit == hit).mean() > 0.995
    both = hit & got_hit
    assert np.allclose(v[..., 2][both], t0[both], atol=2e-5)
    assert np.allclose(v[..., 3][both], t1[both], atol=2e-5)


TURNS = """#version 450 core
#include "fibers/shape.glsl"
uniform float uSpan;
layout(location = 0) out vec4 outValue;
void main() {
    float x = (floor(gl_FragCoord.y) * 64.0 + floor(gl_FragCoord.x)) / 4096.0 * 2.0 * uSpan - uSpan;
    outValue = vec4(turn_cos_sin(x), x, 0.0);
}
"""


@pytest.mark.parametrize("span", [1.0, 9.0, 70.0])
def test_turn_cos_sin_is_the_float64_cosine_and_sine(ctx, span):
    """The curl's cosine and sine in turns (shape.glsl: turn_cos_sin) against float64, over the angles a
    curled fiber's test meets: a phase in [0, 1), less a twist of up to 8 turns, plus a curl frequency of
    up to 64 turns over the guide. The error is the polynomial's (~1e-7) plus the float32 rounding of x
    itself, which grows with |x| as it does for the built-in cos and sin."""
    from tests.support.glsl_harness import run_fragment

    out = run_fragment(ctx, TURNS, (64, 64), lambda prog: setattr(prog["uSpan"], "value", span))
    x = out[..., 2]           # the float32 argument the shader used, exact in float64
    err = np.hypot(out[..., 0] - np.cos(2 * np.pi * x), out[..., 1] - np.sin(2 * np.pi * x))
    assert np.isfinite(out[..., :2]).all()
    assert err.max() < 4e-7, err.max()
    quarters = np.isclose(4 * x, np.round(4 * x), atol=0, rtol=0)
    assert quarters.any() and (err[quarters] < 2e-7).all()      # exact quarter turns land on the axes


SCALES = """#version 450 core
#include "fibers/shape.glsl"
layout(location = 0) out vec4 outValue;
void main() {
    float v = floor(gl_FragCoord.x) / 63.0 * 2.0 - 0.5;        // [-0.5, 1.5]: past both ends of the guide
    outValue = vec4(shape_scale(v), v, 0.0, 0.0);
}
"""


@pytest.mark.parametrize("ellipsoid", [0.3, 0.6, 1.0])
def test_shape_scale_is_the_float64_scale_and_holds_past_the_guide(ctx, ellipsoid):
    """The ellipsoid's scale (shape.glsl: shape_scale) against its float64 twin, over heights past both
    ends of the guide: a groom's tilted root and tip caps give slabs whose wedges reach there
    (Bangs_100.hair to v = 1.39), and the scale holds its end value rather than closing onto the axis."""
    from app.fibers import Shape, shape_scale
    from tests.support.glsl_harness import run_fragment

    out = run_fragment(ctx, SCALES, (64, 1), lambda prog: setattr(prog["uEllipsoid"], "value", ellipsoid))
    v = out[0, :, 1]
    want = shape_scale(Shape(ellipsoid, 0.0, 0, 0.0, 0.0, 0), v)
    assert np.allclose(out[0, :, 0], want, atol=2e-7)
    ends = shape_scale(Shape(ellipsoid, 0.0, 0, 0.0, 0.0, 0), np.array([0.0, 1.0]))
    assert np.allclose(want[v < 0], ends[0]) and np.allclose(want[v > 1], ends[1])
    assert (v < -0.4).any() and (v > 1.4).any()
