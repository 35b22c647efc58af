"""Colour along the strand (issue 15): the root-to-tip gradient, the groom file's own colours per guide,
the random tint, and the panel's swatches.

The colour function has one owner per language: glsl/shading/fiber_color.glsl (the shader and the
explicit baseline), app/render/look.py fiber_color (numpy) and osl/shading/fiber_color.osl (Cycles).
These tests hold them to each other and follow the colours from the bytes of a file to the pixels.
"""

from __future__ import annotations

import shutil
import struct
import tempfile
from pathlib import Path

import numpy as np
import pytest

from app.gl.shaders import ProgramCache, glsl_root
from app.params import Params
from app.render import look
from app.render.camera import Camera
from app.render.explicit import ExplicitRenderer
from app.render.renderer import Renderer, scene_gpu_bytes
from app.scene.containers import Scene
from app.scene.generators import build_scene
from app.scene.grooms import load_groom, scene_from_groom
from app.scene.grooms.groom import srgb_to_linear
from tests.scene.test_grooms import hair_bytes, ply_bytes
from tests.support.paths import HAIR_DATA, ROOT

SIZE = (160, 120)
# a side view of one straight vertical clump: image rows run root (bottom) to tip (top)
SIDE = {"scene.generator": "single", "scene.radius": 0.25, "scene.length": 4.0, "fibers.phi_step": 3.0,
        "fibers.length_jitter": 0.0, "camera.elevation": 0.0, "look.tint_variation": 0.0}
GRADIENT = {"look.tip_blend": 1.0, "look.tip_start": 0.0, "look.tip_color": (1.0, 1.0, 1.0)}


def _render(renderer, values, scene=None, size=SIZE, **kw):
    p = Params(values)
    scene = scene if scene is not None else build_scene(p)
    renderer.set_scene(scene)
    cam = Camera.from_params(p, scene, size[0] / size[1])
    return renderer.render(p, cam, size, outputs=("color", "ids"), **kw)


# ------------------------------------------------------------------------------------------ the function

def test_tip_weight_is_zero_to_start_then_rises_to_blend():
    v = np.linspace(0.0, 1.0, 101)
    w = look.tip_weight(v, 0.7, 0.4)
    assert (w[v <= 0.4] == 0).all()
    assert np.all(np.diff(w) >= 0) and w[-1] == pytest.approx(0.7)
    assert np.isfinite(look.tip_weight(v, 1.0, 1.0)).all() and look.tip_weight(v, 1.0, 1.0).max() == 0.0
    assert look.tip_weight(v, 0.0, 0.0).max() == 0.0


def test_no_gradient_is_the_look_colour_bit_for_bit():
    p = Params({"look.tint_variation": 0.3})
    tint = np.linspace(-0.5, 0.5, 11)
    got = look.fiber_color(np.linspace(0, 1, 11), tint, p)
    want = np.clip(np.asarray(look.base_color(p)) * (1 + 0.3 * 2 * tint[:, None]), 0, 1)
    assert np.array_equal(got, want)


def test_melanin_mode_blends_to_the_tip_melanin():
    p = Params({"look.color_mode": "melanin", "look.melanin": 0.8, "look.tip_melanin": 0.1,
                "look.tip_blend": 1.0, "look.tip_start": 0.0, "look.tint_variation": 0.0})
    c = look.fiber_color(np.array([0.0, 1.0]), np.zeros(2), p)
    assert np.allclose(c[0], look.base_color(p)) and np.allclose(c[1], look.tip_color(p))
    assert c[1].sum() > c[0].sum() * 2      # less melanin at the tips: lighter


@pytest.fixture(scope="module")
def glsl_colors(ctx):
    """fiber_color.glsl evaluated for a grid of (guide, v, tint) through a tiny fragment pass."""
    frag = """#version 450 core
#include "shading/fiber_color.glsl"
uniform int uW;
layout(location = 0) out vec4 outValue;
void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    uint guide = uint(px.y % 4);
    float v = float(px.x) / float(uW - 1) * 1.2 - 0.1;        // past both ends too
    float tint = float(px.y / 4) / 7.0 - 0.5;
    outValue = vec4(fiber_color(guide, v, tint), tip_weight(v, uTipBlend, uTipStart));
}
"""
    tmp = Path(tempfile.mkdtemp())
    shutil.copytree(glsl_root(), tmp / "glsl")
    (tmp / "glsl" / "colour_probe.frag").write_text(frag)
    prog = ProgramCache(tmp / "glsl").get(ctx, "stages/fullscreen.vert", "colour_probe.frag")
    W, H = 64, 32
    guides = np.array([[[0.9, 0.1, 0.1], [0.1, 0.9, 0.2]], [[0.2, 0.3, 0.8], [0.2, 0.3, 0.8]],
                       [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]], [[0.5, 0.4, 0.3], [0.05, 0.02, 0.01]]], np.float32)
    scene = Scene(np.zeros((4, 20), np.float32), guide_colors=guides)
    scene.segments[:, 19] = np.arange(4)
    buf = ctx.buffer(scene.guide_color_rows().tobytes())
    target = ctx.texture((W, H), 4, dtype="f4")
    fbo = ctx.framebuffer([target])
    out = {}
    for source, p in (("look", Params({**GRADIENT, "look.tip_start": 0.3, "look.tip_blend": 0.8,
                                       "look.tint_variation": 0.4})),
                      ("file", Params({"look.tip_start": 0.6, "look.tip_blend": 0.5, "look.tint_variation": 0.2,
                                       "look.color_source": "file"}))):
        for name, value in (("uBaseColor", look.base_color(p)), ("uTipColor", look.tip_color(p)),
                            ("uTipBlend", p["look.tip_blend"]), ("uTipStart", p["look.tip_start"]),
                            ("uTintVariation", p["look.tint_variation"]), ("uGuideColors", int(source == "file")),
                            ("uW", W)):
            prog[name].value = value
        buf.bind_to_storage_buffer(4)
        fbo.use()
        ctx.viewport = (0, 0, W, H)
        ctx.vertex_array(prog, []).render(vertices=3)
        out[source] = (p, np.frombuffer(target.read(), np.float32).reshape(H, W, 4).copy())
    ctx.framebuffer(ctx.renderbuffer((1, 1))).use()
    for obj in (fbo, target, buf):
        obj.release()
    shutil.rmtree(tmp)
    y, x = np.mgrid[0:H, 0:W]
    return out, guides, y % 4, x / (W - 1) * 1.2 - 0.1, (y // 4) / 7.0 - 0.5


def test_glsl_fiber_color_matches_numpy(glsl_colors):
    out, guides, guide, v, tint = glsl_colors
    for source, (p, got) in out.items():
        root = guides[guide, 0] if source == "file" else None
        tip = guides[guide, 1] if source == "file" else None
        want = look.fiber_color(v, tint, p, root, tip)
        assert np.abs(got[..., :3] - want).max() < 2e-6, source
        assert np.abs(got[..., 3] - look.tip_weight(v, p["look.tip_blend"], p["look.tip_start"])).max() < 1e-6


# --------------------------------------------------------------------------------------- in the picture

def _row_profile(frame, base):
    """Mean brightness change per image row band (bottom = root first) where both frames show a fiber."""
    hit = (frame.ids[..., 0] > 0) & (base.ids[..., 0] > 0)
    change = frame.color.astype(np.float64).sum(-1) - base.color.astype(np.float64).sum(-1)
    rows = np.flatnonzero(hit.any(1))
    bands = np.array_split(rows[::-1], 8)       # image row 0 is the top: reverse for root first
    return np.array([change[b][hit[b]].mean() for b in bands])


def test_gradient_brightens_monotonically_root_to_tip(renderer):
    base = _render(renderer, SIDE)
    grad = _render(renderer, {**SIDE, **GRADIENT})
    assert np.array_equal(base.ids, grad.ids), "colour must not move a fiber"
    prof = _row_profile(grad, base)
    assert prof[-1] > 60, prof                      # the tips turn nearly white
    assert np.all(np.diff(prof) > 0), prof          # every band lighter than the one below it
    # tip_start = 0.5: the root half keeps its colour bit for bit
    half = _render(renderer, {**SIDE, **GRADIENT, "look.tip_start": 0.5})
    prof = _row_profile(half, base)
    assert abs(prof[0]) == 0 and abs(prof[1]) == 0 and prof[-1] > 60, prof


@pytest.mark.parametrize("extreme", [
    {"look.tip_blend": 1.0, "look.tip_start": 1.0},
    {"look.tip_blend": 1.0, "look.tip_start": 0.0, "look.tip_color": (0.0, 0.0, 0.0)},
    {"look.tip_blend": 1.0, "look.tip_start": 0.0, "look.tip_color": (1.0, 1.0, 1.0), "look.tint_variation": 1.0},
    {"look.color_mode": "melanin", "look.tip_melanin": 1.0, "look.tip_blend": 1.0, "look.tip_start": 0.0},
], ids=["start-at-tip", "black-tips", "white-tips-full-tint", "melanin-black-tips"])
def test_extremes_stay_finite_and_keep_every_fiber(renderer, extreme):
    """At the ends of their ranges the controls recolour fibers and nothing else: same ids (no holes), and
    the float32 colour target (the extremes bench's) holds no NaN."""
    values = {**SIDE, "scene.taper": 0.9, "camera.elevation": 80.0}   # grazing along a thin tapered clump
    base = _render(renderer, values)
    got = _render(renderer, {**values, **extreme})
    assert np.array_equal(base.ids, got.ids)
    old = Renderer.COLOR_DTYPE
    Renderer.COLOR_DTYPE = "f4"
    try:
        f = _render(renderer, {**values, **extreme})
    finally:
        Renderer.COLOR_DTYPE = old
    assert f.color is None or np.isfinite(np.asarray(f.color, np.float64)).all()


def test_start_at_the_tip_changes_nothing(renderer):
    base = _render(renderer, SIDE)
    same = _render(renderer, {**SIDE, "look.tip_blend": 1.0, "look.tip_start": 1.0})
    assert np.array_equal(base.color, same.color)


# ------------------------------------------------------------------------------ groom files' colours

def _strands(n=2, length=4.0, spacing=1.5):
    """n straight vertical strands (Z up), 5 vertices each, side by side along X."""
    t = np.linspace(0, 1, 5)[:, None]
    return [np.array([spacing * i, 0.0, 0.0]) + t * np.array([0.0, 0.0, length]) for i in range(n)]


RED_GREEN = [np.array([[0.9, 0.05, 0.05]] * 5), np.array([[0.05, 0.9, 0.05]] * 5)]


def _tfx_with_colors(strands, colors) -> bytes:
    ns, nv = len(strands), len(strands[0])
    xyzw = np.ones((ns, nv, 4), "<f4")
    xyzw[:, :, :3] = np.stack(strands)
    rgba = np.ones((ns, nv, 4), "<f4")
    rgba[:, :, :3] = np.stack(colors)
    o_col = 160 + xyzw.nbytes
    head = struct.pack("<f7I", 4.0, ns, nv, 160, 0, 0, 0, o_col) + bytes(128)
    return head + xyzw.tobytes() + rgba.tobytes()


def _ply_with_colors(strands, colors8) -> bytes:
    data = bytearray(ply_bytes(strands))
    head_end = data.index(b"end_header\n") + len(b"end_header\n")
    pts = np.concatenate(strands)
    vert = np.frombuffer(bytes(data[head_end:head_end + 15 * len(pts)]), [
        ("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("red", "u1"), ("green", "u1"), ("blue", "u1")]).copy()
    c = np.concatenate(colors8)
    vert["red"], vert["green"], vert["blue"] = c.T
    data[head_end:head_end + 15 * len(pts)] = vert.tobytes()
    return bytes(data)


def _groom_file(tmp_path, fmt, strands, colors):
    """A synthetic groom of each format with per-vertex colours; returns (path, the linear colours)."""
    if fmt == "hair":
        body = hair_bytes(strands, colors=colors)
        linear = [srgb_to_linear(c) for c in colors]
    elif fmt == "tfx":
        body = _tfx_with_colors(strands, colors)
        linear = [srgb_to_linear(c) for c in colors]
    else:
        c8 = [np.round(c * 255).astype(np.uint8) for c in colors]
        body = _ply_with_colors(strands, c8)
        linear = [srgb_to_linear(c / 255.0) for c in c8]
    path = tmp_path / f"colours.{fmt}"
    path.write_bytes(body)
    return path, linear


@pytest.mark.parametrize("fmt", ["hair", "tfx", "ply"])
def test_file_colours_are_read_per_guide(tmp_path, fmt):
    ramp = [np.linspace([0.9, 0.1, 0.1], [0.2, 0.2, 0.9], 5), np.linspace([0.1, 0.8, 0.1], [0.7, 0.7, 0.7], 5)]
    path, linear = _groom_file(tmp_path, fmt, _strands(), ramp)
    g = load_groom(path, up="z")
    assert g.colors is not None
    scene = scene_from_groom(Params({"scene.generator": "groom", "scene.groom_file": str(path),
                                     "scene.groom_up": "z"}))
    assert scene.guide_colors.shape == (2, 2, 3)
    want = np.stack([np.stack([c[0], c[-1]]) for c in linear])
    assert np.abs(scene.guide_colors - want).max() < 1e-6
    assert scene_gpu_bytes(scene) - scene_gpu_bytes(Scene(scene.segments, scene.origin)) == 2 * 32


def test_a_groom_without_colours_has_none(tmp_path):
    path = tmp_path / "plain.hair"
    path.write_bytes(hair_bytes(_strands()))
    scene = scene_from_groom(Params({"scene.generator": "groom", "scene.groom_file": str(path),
                                     "scene.groom_up": "z"}))
    assert scene.guide_colors is None


def test_clustered_guides_take_their_members_mean(tmp_path):
    strands = _strands(4, spacing=0.05) + [s + np.array([10.0, 0, 0]) for s in _strands(2, spacing=0.05)]
    colors = [np.array([[c, 0.5, 0.5]] * 5) for c in (0.2, 0.4, 0.6, 0.8, 1.0, 0.0)]
    path, linear = _groom_file(tmp_path, "hair", strands, colors)
    scene = scene_from_groom(Params({"scene.generator": "groom", "scene.groom_file": str(path),
                                     "scene.groom_up": "z", "scene.groom_cluster": 2}))
    reds = sorted(scene.guide_colors[:, 0, 0].tolist())
    assert reds == pytest.approx(sorted([np.mean([c[0, 0] for c in linear[:4]]),
                                         np.mean([c[0, 0] for c in linear[4:]])]), abs=1e-6)


@pytest.mark.parametrize("fmt", ["hair", "tfx", "ply"])
@pytest.mark.parametrize("visibility", ["proxies", "walk"])
def test_file_colours_reach_the_pixels(renderer, tmp_path, fmt, visibility):
    """A red strand and a green strand: with look.color_source = file each guide's fibers take its
    strand's hue (whichever way the renderer finds containers); with the look's colour they are alike."""
    path, _ = _groom_file(tmp_path, fmt, _strands(), RED_GREEN)
    values = {"scene.generator": "groom", "scene.groom_file": str(path), "scene.groom_up": "z",
              "camera.elevation": 0.0, "camera.azimuth": 90.0, "quality.visibility": visibility}
    scene = scene_from_groom(Params(values))
    f = _render(renderer, {**values, "look.color_source": "file"}, scene)
    lk = _render(renderer, values, scene)
    assert np.array_equal(f.ids, lk.ids)
    ratios = {}
    for guide in (1, 2):
        m = f.ids[..., 0] == guide
        assert m.sum() > 50
        c = f.color[m].astype(np.float64).mean(0)
        ratios[guide] = c[0] / max(c[1], 1.0)
        base = lk.color[m].astype(np.float64).mean(0)
        assert base[0] > base[1] > base[2]          # the look's brown on both
    assert ratios[1] > 2.0 and ratios[2] < 0.5, ratios


def test_explicit_baseline_draws_the_same_colours(ctx, tmp_path):
    """The explicit ribbons shade through the same colour function: with the file's colours and a
    gradient on, where both renderers show the same fiber their colours differ no more than they do
    for the plain look (the ribbon's own approximations), while the look itself moved a lot."""
    path, _ = _groom_file(tmp_path, "hair", _strands(), RED_GREEN)
    values = {"scene.generator": "groom", "scene.groom_file": str(path), "scene.groom_up": "z",
              "camera.elevation": 0.0, "camera.azimuth": 90.0, "fibers.phi_step": 3.0}
    scene = scene_from_groom(Params(values))
    virtual, explicit = Renderer(ctx), ExplicitRenderer(ctx)
    diffs, frames = {}, {}
    try:
        for name, extra in (("plain", {}), ("coloured", {"look.color_source": "file", **GRADIENT,
                                                         "look.tip_start": 0.4})):
            p = Params({**values, **extra})
            virtual.set_scene(scene)
            explicit.set_scene(scene, p)
            cam = Camera.from_params(p, scene, SIZE[0] / SIZE[1])
            fv = virtual.render(p, cam, SIZE, outputs=("color", "ids"), mode="exact")
            fe = explicit.render(p, cam, SIZE, outputs=("color", "ids"))
            same = np.all(fv.ids[..., :3] == fe.ids[..., :3], -1) & (fv.ids[..., 0] > 0)
            assert same.sum() > 200
            d = np.abs(fv.color.astype(np.int16) - fe.color.astype(np.int16))[same]
            diffs[name] = float(d.mean())
            frames[name] = (fv, same)
    finally:
        virtual.release_targets()
        explicit.release()
        explicit.release_targets()
    moved = np.abs(frames["coloured"][0].color.astype(np.int16)
                   - frames["plain"][0].color.astype(np.int16))[frames["plain"][1]].mean()
    assert moved > 20, moved
    assert diffs["coloured"] <= diffs["plain"] + 2.0, diffs


def test_the_five_shared_grooms_colours():
    """Which shared grooms carry colours (docs/grooms.md): only Curly_100.ply, one colour per strand,
    spread over the whole range (a per-strand id palette rather than hair colour)."""
    found = {}
    for f in sorted(HAIR_DATA.glob("*.*")):
        if f.suffix == ".md":
            continue
        g = load_groom(f)
        found[f.name] = g.colors is not None
        if g.colors is not None:
            ends = g.strand_end_colors()
            assert np.abs(ends[:, 0] - ends[:, 1]).max() < 1e-9      # the same colour root to tip
            assert ends.reshape(-1, 3).std(0).min() > 0.2            # and all over the range
    assert found == {"Bangs_100.hair": False, "Curly_100.ply": True, "Ratboy_mohawk.tfx": False,
                     "harolongo.data": False, "sintel_hair.tfx": False}


# ------------------------------------------------------------------------------------------- swatches

def test_display_swatch_is_the_linear_colour_through_the_display_power():
    assert look.display_color((0.55, 0.36, 0.2)) == (194, 160, 123)
    assert look.display_color((0.0, 1.0, 0.5)) == (0, 255, round(0.5 ** (1 / 2.2) * 255))


@pytest.mark.parametrize("values", [
    {}, {"look.color": (0.2, 0.5, 0.8)}, {"look.model": "marschner"}, {"look.color_mode": "melanin"},
    {"look.shadow_density": 1.0}, {"look.light_intensity": 4.0}, {"look.self_shadow": "off"},
], ids=["default", "blue", "marschner", "melanin", "dense-shadow", "bright-key", "no-shadow"])
def test_lit_swatch_predicts_the_rendered_fibers(renderer, values):
    """The 'as lit' swatch against the median of the lit fibers in the default preset's picture: within
    8 levels (of 255) per channel. (The panel's old swatch, the linear numbers shown as display values,
    was 48 levels off in blue for the default brown.)"""
    from app.presets import load_preset

    pre = load_preset(ROOT / "presets" / "default.toml")
    pre = getattr(pre, "params", pre)
    p = pre.replace(**values)
    scene = build_scene(p)
    renderer.set_scene(scene)
    size = (320, 180)
    f = renderer.render(p, Camera.from_params(p, scene, size[0] / size[1]), size, outputs=("color", "ids"))
    median = np.median(f.color[f.ids[..., 0] > 0].astype(np.float64), axis=0)
    swatch = np.array(look.lit_swatch(p))
    assert np.abs(swatch - median).max() <= 8, (swatch, median)


# ------------------------------------------------------------------------------------------ OSL / Cycles

def test_blend_face_attributes_carry_each_faces_guide_colours(tmp_path):
    from app.export import blend as XB

    path, linear = _groom_file(tmp_path, "hair", _strands(), RED_GREEN)
    scene = scene_from_groom(Params({"scene.generator": "groom", "scene.groom_file": str(path),
                                     "scene.groom_up": "z"}))
    verts, faces, sizes, rows = XB.container_boxes(scene.segments)
    attrs = XB.color_face_attributes(scene.segments, rows, scene.guide_colors)
    assert set(attrs) == set(XB.COLOR_ATTRIBUTES)
    guide = scene.segments[rows, 19].astype(int)
    for end, name in enumerate(XB.COLOR_ATTRIBUTES):
        want = np.stack([linear[g][0 if end == 0 else -1] for g in guide])
        assert np.abs(attrs[name] - want).max() < 1e-6


def _blender():
    from tests.export.test_osl_export import HAVE_BPY
    if not HAVE_BPY:
        pytest.skip("bpy is not installed: pip install 'vfiber[blender]'")
    from app.export import blender as B

    ok, why = B.blender_available()
    if not ok:
        pytest.skip(f"Blender harness unavailable: {why}")
    return B


def test_osl_fiber_color_matches_numpy_in_cycles(tmp_path):
    """vf_fiber_color / vf_tip_weight in Cycles against look.fiber_color, value by value (float32)."""
    from tests.export.test_osl_export import _probe

    B = _blender()
    rng = np.random.default_rng(3)
    n = 600
    v = rng.uniform(-0.1, 1.1, n)
    tint = rng.uniform(-0.5, 0.5, n)
    use = (np.arange(n) % 2).astype(int)
    root, tip = rng.uniform(0, 1, (n, 3)), rng.uniform(0, 1, (n, 3))
    p = Params({"look.tip_blend": 0.7, "look.tip_start": 0.35, "look.tint_variation": 0.3,
                "look.tip_color": (0.9, 0.8, 0.6)})
    arrays = {"a_v": ("float", v), "a_t": ("float", tint), "a_use": ("int", use),
              **{f"a_r{c}": ("float", root[:, c]) for c in range(3)},
              **{f"a_p{c}": ("float", tip[:, c]) for c in range(3)}}
    base, tc = look.base_color(p), look.tip_color(p)
    body = "\n".join([
        f"    if (k < {n}) {{",
        "        value = vf_fiber_color(color({!r}, {!r}, {!r}), color({!r}, {!r}, {!r}), a_use[k],".format(*base, *tc),
        "                               color(a_r0[k], a_r1[k], a_r2[k]), color(a_p0[k], a_p1[k], a_p2[k]),",
        f"                               a_v[k], {p['look.tip_blend']!r}, {p['look.tip_start']!r},"
        f" {p['look.tint_variation']!r}, a_t[k]);",
        "    }"])
    got = _probe(B, tmp_path, "vf_colour_probe", arrays, body, n)
    want = np.empty((n, 3))
    for u in (0, 1):
        m = use == u
        want[m] = look.fiber_color(v[m], tint[m], p, root[m] if u else None, tip[m] if u else None)
    assert np.abs(got - want).max() < 1e-5


def test_exported_blend_shows_the_files_colours(tmp_path):
    """export-blend of a red and a green strand with look.color_source = file: Cycles shades each guide
    with its strand's hue (the per-face attributes reach the shader)."""
    import json
    import subprocess
    import sys

    _blender()
    from tests.export.test_blender_export import _render_like_a_farm

    path, _ = _groom_file(tmp_path, "hair", _strands(), RED_GREEN)
    blend = tmp_path / "c.blend"
    code = "import sys; from app.cli import main; sys.exit(main(sys.argv[1:]))"
    sets = ["scene.groom_up=z", "camera.elevation=0", "camera.azimuth=90", "look.color_source=file",
            "fibers.phi_step=4"]
    proc = subprocess.run([sys.executable, "-c", code, "export-blend", str(path), "-o", str(blend), "--size",
                           "96x72", *[a for s in sets for a in ("--set", s)]], capture_output=True, text=True,
                          cwd=str(ROOT), timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    _render_like_a_farm(blend, tmp_path / "c.npy", "--samples", "4")
    rgba = np.load(tmp_path / "c.npy")
    covered = rgba[..., 3] > 0.5
    cols = np.flatnonzero(covered.any(0))
    left, right = cols[: len(cols) // 3], cols[-len(cols) // 3:]
    hue = {}
    for name, cs in (("left", left), ("right", right)):
        px = rgba[:, cs][covered[:, cs]][:, :3]
        hue[name] = float(px[:, 0].mean() / max(px[:, 1].mean(), 1e-6))
    # which strand is on which side depends on the camera; one is red, the other green
    assert max(hue.values()) > 2.0 and min(hue.values()) < 0.5, json.dumps(hue)


# ------------------------------------------------------------------------------- presets, --set, modes

def test_colour_controls_come_from_presets_and_set():
    from app.params import parse_assignment
    from app.presets import loads_preset

    text = ('version = 2\nname = "sunlit"\n[look]\ntip_blend = 0.6\ntip_start = 0.25\n'
            'tip_color = [0.9, 0.8, 0.6]\ncolor_source = "file"\n')
    pre = loads_preset(text, "sunlit.toml")
    p = getattr(pre, "params", pre)
    assert (p["look.tip_blend"], p["look.tip_start"], p["look.color_source"]) == (0.6, 0.25, "file")
    assert p["look.tip_color"] == (0.9, 0.8, 0.6)
    from app.cli import resolve_params

    q, _ = resolve_params(str(ROOT / "presets" / "default.toml"), ["look.tip_color=0.9,0.8,0.6",
                                                                   "look.tip_melanin=0.1"])
    assert q["look.tip_color"] == (0.9, 0.8, 0.6) and q["look.tip_melanin"] == 0.1
    assert Params(dict([parse_assignment("look.tip_color=[0.9, 0.8, 0.6]")]))["look.tip_color"] == (0.9, 0.8, 0.6)
    with pytest.raises(Exception, match="look.tip_blend"):
        Params({"look.tip_blend": 1.5})
    with pytest.raises(Exception, match="look.color_source"):
        Params({"look.color_source": "files"})


@pytest.mark.parametrize("thin_fiber_filter", ["off", "coverage"])
def test_exact_equals_brute_with_colours_on(renderer, tmp_path, thin_fiber_filter):
    """Colour is applied after the traversal: exact and brute find the same fibers and so the same
    colours, gradient and the file's colours included. The filter (the default since #16) colours exact
    mode's frames only, by coverage: the same fibers still, so the ids stay brute force's."""
    path, _ = _groom_file(tmp_path, "ply", _strands(), RED_GREEN)
    values = {"scene.generator": "groom", "scene.groom_file": str(path), "scene.groom_up": "z",
              "camera.elevation": 0.0, "camera.azimuth": 90.0, "fibers.phi_step": 6.0, "look.color_source": "file",
              **GRADIENT, "look.tip_start": 0.3, "quality.filter": thin_fiber_filter}
    scene = scene_from_groom(Params(values))
    exact = _render(renderer, values, scene, size=(96, 72), mode="exact")
    brute = _render(renderer, values, scene, size=(96, 72), mode="brute")
    assert np.array_equal(exact.ids[..., :3], brute.ids[..., :3])
    if thin_fiber_filter == "off":
        assert np.array_equal(exact.color, brute.color)
