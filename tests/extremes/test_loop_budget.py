"""llvmpipe's loop budget: an invocation that passes 65,535 loop-header passes has every loop cut short in
silence. These tests pin how the driver counts, that the traversal reports a budget run out (the canary in
glsl/fibers/traverse.glsl), and that the renderer's draws never run it out."""

from __future__ import annotations

import numpy as np
import pytest

import app.render.renderer as renderer_module
from app.params import Params
from app.render.camera import Camera
from app.render.renderer import LOOP_CAP
from app.scene.containers import Scene

VERT = "#version 450 core\nin vec2 p;\nvoid main() { gl_Position = vec4(p, 0.0, 1.0); }\n"
FRAG = """#version 450 core
uniform int N;
uniform int M;
out vec4 o;
void main() {
    int inner = 0, outer = 0;
    for (int i = 0; i < N; i++) { outer++; for (int j = 0; j < M; j++) inner++; }
    int canary = 0;
    for (int k = 0; k < 5 + N % 2; k++) canary++;
    o = vec4(float(inner), float(outer), float(canary), 1.0);
}
"""


@pytest.fixture()
def loops(ctx, gl):
    if "llvmpipe" not in gl.renderer:
        pytest.skip(f"the loop budget is llvmpipe's; this is {gl.renderer}")
    import moderngl

    prog = ctx.program(vertex_shader=VERT, fragment_shader=FRAG)
    vbo = ctx.buffer(np.array([-1, -1, 3, -1, -1, 3], np.float32).tobytes())
    vao = ctx.vertex_array(prog, [(vbo, "2f", "p")])
    tex = ctx.texture((1, 1), 4, dtype="f4")
    fbo = ctx.framebuffer([tex])

    def run(n, m):
        fbo.use()
        ctx.viewport = (0, 0, 1, 1)
        ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE | moderngl.BLEND)
        prog["N"].value, prog["M"].value = n, m
        vao.render()
        return np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32)[:3]

    yield run
    # the 1x1 target stays: moderngl rebinds the previous framebuffer after making one, and rebinding a
    # released one is an invalid operation
    for o in (vao, vbo, prog):
        o.release()


def test_llvmpipe_counts_every_pass_through_a_loop_header(loops):
    """An empty inner loop still costs one pass (its failing test): 65,536 passes buy 32,768 outer
    iterations. The renderer's chunk sizes rest on this rule."""
    inner, outer, canary = loops(70_000, 0)
    assert outer == 32_768 and canary < 5
    inner, outer, canary = loops(5_000, 16)
    assert inner + 2 * outer == pytest.approx(65_536, abs=8)   # 16 + 1 passes inside, 1 outside
    inner, outer, canary = loops(1_001, 16)
    assert (inner, outer, canary) == (16_016, 1_001, 6), "under the budget every loop runs to the end"


SCENE = Scene.from_polylines([np.array([[0, 0, 0], [0, 0, 2.0]])], 1.0)
CAM = Camera([4.0, 1.0, 1.3], [0, 0, 1.0], 35, 0.5, 20)
# thin curled fibers met at a slant: nearly every test runs the whole chord loop and finds nothing
CURLED = {"fibers.rings": 1, "fibers.phi_step": 0.1, "fibers.fiber_radius": 0.02, "fibers.length_jitter": 0.0,
          "shape.curl_amplitude": 0.5, "shape.curl_frequency": 64.0}


def test_brute_curved_draws_stay_within_the_loop_budget(renderer, monkeypatch):
    """Regression: BRUTE_CHUNK_SHAPED counted MAX_SUB + 1 passes per curved test, but the candidate loop and
    the chord loop's final test make it MAX_SUB + 2, so a 1,919-fiber draw could need 69,000 passes and
    lost fibers (144 of 256 pixels cut short here, one pixel's fiber wrong)."""
    p = Params(CURLED)
    renderer.set_scene(SCENE)
    whole = renderer.render(p, CAM, (16, 16), outputs=("ids", "iters"), mode="brute")
    assert 0 < whole.iters.max() < LOOP_CAP, "a brute draw ran out of loop budget"
    monkeypatch.setattr(renderer_module, "BRUTE_CHUNK_SHAPED", renderer_module.BRUTE_CHUNK_SHAPED // 3)
    finer = renderer.render(p, CAM, (16, 16), outputs=("ids",), mode="brute")
    assert finer.draws > whole.draws
    assert (whole.ids[..., :3] == finer.ids[..., :3]).all()


def test_a_budget_run_out_is_reported(renderer, monkeypatch):
    """The canary: with the chunks made far too big, the iters output shows LOOP_CAP instead of the loss
    passing unnoticed."""
    monkeypatch.setattr(renderer_module, "BRUTE_CHUNK_SHAPED", 3600)
    renderer.set_scene(SCENE)
    frame = renderer.render(Params(CURLED), CAM, (16, 16), outputs=("iters",), mode="brute")
    assert frame.iters.max() >= LOOP_CAP


def test_exact_splits_its_draws_when_one_cannot_hold_the_candidates(renderer):
    """Regression: a curled fiber's reach can be its whole ring, so every arc of a ray tests all 3,600
    fibers at up to 18 loop passes each; exact mode drew once and its fragments ran out of loop budget
    (the canary fired in 24-72 of 256 pixels per draw, and at 0.01 degrees exact showed 0 of brute's 38
    fiber pixels). It now draws the fibers in ranges sized by a bound on the candidates (draw_ranges)."""
    p = Params(CURLED)
    renderer.set_scene(SCENE)
    exact = renderer.render(p, CAM, (16, 16), outputs=("ids", "iters"), mode="exact")
    brute = renderer.render(p, CAM, (16, 16), outputs=("ids", "iters"), mode="brute")
    assert exact.iters.max() < LOOP_CAP and brute.iters.max() < LOOP_CAP, "a draw ran out of loop budget"
    assert exact.draws > 2, "one draw per pass cannot hold these candidates"
    assert exact.hit.sum() > 100
    assert (exact.ids[..., :3] == brute.ids[..., :3]).all()


LAYOUTS = [
    {},
    {"fibers.rings": 64, "fibers.phi_step": 0.01, "fibers.fiber_radius": 0.5 / 64},
    {"fibers.rings": 64, "fibers.phi_step": 0.01, "fibers.fiber_radius": 1e-4, "fibers.phi_increment": 3.0},
    {"fibers.rings": 1, "fibers.phi_step": 0.01, "shape.ellipsoid": 1.0},
    {"fibers.rings": 7, "fibers.phi_step": 0.3, "shape.twist": -8.0, "shape.twist_pattern": "ramped",
     "shape.curl_amplitude": 0.5, "quality.supersample": 3, "look.self_shadow": "traced"},
]


@pytest.mark.parametrize("values", LAYOUTS, ids=range(len(LAYOUTS)))
def test_draw_ranges_cover_every_fiber_once(values):
    from app import reference
    from app.render.renderer import draw_ranges, traversals_per_fragment
    from app.scene.generators import build_scene

    p = Params({"scene.count": 4, "scene.segments": 3, "scene.bend": 50.0, **values})
    scene = build_scene(p)
    total = reference.ring_layout(p).fibers_per_container
    for mode in ("fast", "exact", "brute"):
        ranges = draw_ranges(p, scene, mode, traversals_per_fragment(p, mode))
        assert ranges[0][0] == 0 and ranges[-1][1] == total
        assert all(a < b for a, b in ranges) and all(r[1] == s[0] for r, s in zip(ranges, ranges[1:]))


def test_bundled_presets_need_one_draw():
    """The bound is loose on purpose; it must not cost the layouts people use a second draw."""
    from app.presets import bundled_presets
    from app.render.renderer import draw_ranges, traversals_per_fragment
    from app.scene.generators import build_scene

    for preset in bundled_presets():
        p = preset.params
        assert len(draw_ranges(p, build_scene(p), "exact", traversals_per_fragment(p, "exact"))) == 1, preset.name


def test_ring_order_only_where_the_budget_is_tight(renderer):
    """The loops after the ring loop go by ring index (same ring in every lane of a SIMD batch) only where
    the lanes' own order could pass the budget: it costs a few percent. Both orders find the same fibers."""
    from app.presets import bundled_presets
    from app.render.renderer import needs_ring_order, traversals_per_fragment
    from app.scene.generators import build_scene

    for preset in bundled_presets():
        p = preset.params
        assert not needs_ring_order(p, build_scene(p), "exact", traversals_per_fragment(p, "exact")), preset.name
    # the rings' costs fall inwards here (even spacing thins the inner rings; a twist near 4.2 turns makes
    # the outer rings' chords sweep far), so a lane coming back out could pay the outer rings' cost at
    # every pass: by ring it is
    p = Params({"scene.count": 4, "fibers.even_spacing": 1.0, "fibers.phi_step": 0.5, "shape.twist": 4.2,
                "shape.curl_amplitude": 0.3})
    scene = build_scene(p)
    assert needs_ring_order(p, scene, "exact")
    renderer.set_scene(scene)
    from app.render.camera import Camera as Cam

    cam = Cam.from_params(p, scene, 1.5)
    exact = renderer.render(p, cam, (48, 32), outputs=("ids", "iters"), mode="exact")
    brute = renderer.render(p, cam, (48, 32), outputs=("ids",), mode="brute")
    assert exact.hit.sum() > 100 and exact.iters.max() < LOOP_CAP
    assert (exact.ids[..., :3] == brute.ids[..., :3]).all()


def test_curved_lanes_in_their_own_order_stay_within_the_budget(renderer, monkeypatch):
    """Curved fibers: a lane's arcs go in by ring and come back out (glsl/fibers/shaped.glsl), so at pass p
    no lane is deeper than ring min(p, 2K - 1 - p) and the bound is twice the sum of the rings' running
    maximum cost. The curled scene of the shapes bench needed the by-ring order under the old bound (the
    innermost ring can take its whole ring on every chord piece) and no longer does; both orders find
    brute force's fibers, and no loop runs out."""
    from app.render.renderer import needs_ring_order
    from app.scene.generators import build_scene

    p = Params({"scene.count": 4, "shape.curl_amplitude": 0.35, "shape.curl_frequency": 6.0})
    scene = build_scene(p)
    assert not needs_ring_order(p, scene, "exact")
    renderer.set_scene(scene)
    cam = Camera.from_params(p.replace(**{"camera.elevation": 60.0}), scene, 1.5)   # caps: many pieces
    own = renderer.render(p, cam, (48, 32), outputs=("ids", "iters"), mode="exact")
    brute = renderer.render(p, cam, (48, 32), outputs=("ids",), mode="brute")
    monkeypatch.setattr(renderer_module, "needs_ring_order", lambda *a, **k: True)
    by_ring = renderer.render(p, cam, (48, 32), outputs=("ids", "iters"), mode="exact")
    assert own.hit.sum() > 100 and own.iters.max() < LOOP_CAP and by_ring.iters.max() < LOOP_CAP
    assert (own.ids[..., :3] == brute.ids[..., :3]).all()
    assert (by_ring.ids[..., :3] == brute.ids[..., :3]).all()


def test_an_ellipsoid_on_a_groom_with_tilted_caps_needs_one_draw():
    """A groom's root and tip caps are tilted, so the wedges of its end slabs reach past the guide
    (Bangs_100.hair to v = 1.39). The ellipsoid's scale holds its end value there (shape.glsl:
    shape_scale); the formula taken on would close every ring onto the axis, the bound would then take
    whole rings on every chord piece, and the frame three draws (2.8x the straight frame's time)."""
    from app.presets import find_preset
    from app.render.renderer import draw_ranges, needs_ring_order, traversals_per_fragment
    from app.scene.generators import build_scene
    from tests.support.paths import HAIR_DATA

    groom = HAIR_DATA / "Bangs_100.hair"
    if not groom.exists():
        pytest.skip(f"{groom} is not here")
    p = find_preset("default").params.replace(**{"scene.generator": "groom", "scene.groom_file": str(groom),
                                                 "shape.ellipsoid": 0.6})
    scene = build_scene(p)
    rays = traversals_per_fragment(p, "exact")
    for walks in (0, 2):        # the proxies strategy, the walk (renderer.py)
        assert len(draw_ranges(p, scene, "exact", rays, walks=walks)) == 1
        assert not needs_ring_order(p, scene, "exact", rays, walks)
