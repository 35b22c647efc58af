"""The clump profile (fibers.edge_density, fibers.edge_width: fewer fibers on the outer rings) and the
clump size of grooms (scene.groom_radius_scale, scene.taper on groom containers).

The profile lives in the ring layout only (app/fibers/layout.py: fibers per ring), so the GLSL takes it
through the per-ring uniforms unchanged; the OSL computes the layout in the shader (osl/fibers/layout.osl:
vf_ring) and is held to the float64 layout in Cycles below.
"""

from __future__ import annotations

import numpy as np
import pytest

from app import reference
from app.fibers import fiber_count, ring_layout
from app.params import ParamError, Params
from app.render.camera import Camera
from app.render.explicit import ExplicitRenderer, compare_frames, fiber_centers
from tests.support.ids import gpu_ids, reference_ids, setup
from tests.support.paths import HAIR_DATA

DATA = HAIR_DATA
needs_data = pytest.mark.skipif(not DATA.is_dir(), reason=f"shared hair data not found at {DATA}")
SIZE = (160, 96)
PROFILE = {"fibers.edge_density": 0.25, "fibers.edge_width": 0.6, "fibers.edge_thickness": 0.4}


# --------------------------------------------------------------------------------------------------
# The layout
# --------------------------------------------------------------------------------------------------
def _old_counts(p: Params) -> np.ndarray:
    """Fibers per ring as the layout counted them before the profile existed (phi_step, phi_increment,
    even_spacing only): the prediction for the default profile."""
    K = p["fibers.rings"]
    i = np.arange(K, dtype=np.float64)
    rho = 1.0 - (i + 0.5) / K
    step = (p["fibers.phi_step"] + i * p["fibers.phi_increment"]) * (
        1.0 + p["fibers.even_spacing"] * (rho[0] / rho - 1.0))
    return np.maximum(1, np.floor(360.0 / step + 0.5)).astype(np.int64)


@pytest.mark.parametrize("values", [{}, {"fibers.rings": 7, "fibers.phi_step": 3.3, "fibers.phi_increment": 1.7,
                                         "fibers.even_spacing": 0.6}, {"fibers.rings": 64, "fibers.phi_step": 0.7,
                                                                       "fibers.fiber_radius": 0.005}])
def test_default_profile_is_todays_layout(values):
    """edge_density 1 is today's layout bit for bit, whatever edge_width says."""
    for width in (0.05, 0.5, 1.0):
        p = Params({**values, "fibers.edge_width": width})
        assert ring_layout(p).n.tolist() == _old_counts(p).tolist()


@pytest.mark.parametrize("rings", [1, 4, 10, 64])
@pytest.mark.parametrize("density,width", [(0.25, 0.6), (0.02, 0.05), (0.5, 1.0), (0.02, 1.0)])
def test_profile_thins_the_outer_rings_only(rings, density, width):
    """The outermost ring holds edge_density of the fibers it held (to the rounding of a whole fiber), a
    ring whose outer boundary lies edge_width or more inside the edge keeps all of its fibers, and in
    between the count never grows toward the edge."""
    base = Params({"fibers.rings": rings, "fibers.fiber_radius": 0.2 / rings})
    p = base.replace(**{"fibers.edge_density": density, "fibers.edge_width": width})
    before, after = ring_layout(base).n, ring_layout(p).n
    assert abs(after[0] - before[0] * density) <= 0.5 + 1e-9 or after[0] == 1
    outer = 1.0 - np.arange(rings) / rings
    core = outer <= 1.0 - width + 1e-12
    assert (after[core] == before[core]).all()
    assert (after <= before).all()
    assert (np.diff(after / before) >= -1e-12).all(), "density must not rise toward the edge"
    thesis, exact = fiber_count(p)
    assert exact == int(after.sum()) and thesis == pytest.approx(
        float((360.0 / (base["fibers.phi_step"] / reference_profile(p))).sum()))


def reference_profile(p: Params) -> np.ndarray:
    """The profile written out once more from its definition: linear in the ring's outer boundary."""
    K = p["fibers.rings"]
    outer = 1.0 - np.arange(K) / K
    t = np.clip((outer - (1.0 - p["fibers.edge_width"])) / p["fibers.edge_width"], 0.0, 1.0)
    return 1.0 - (1.0 - p["fibers.edge_density"]) * t


@pytest.mark.parametrize("rings", [1, 2, 8, 64])
@pytest.mark.parametrize("density", [0.02, 0.3])
@pytest.mark.parametrize("width", [0.05, 1.0])
def test_profile_layout_is_finite_and_fibers_stay_in_their_slots(rings, density, width):
    """At the ends of both ranges, at full jitter and at the thickest fiber a ring allows: every number
    finite, every fiber inside its ring's annulus and inside its angular slot (so the traversal's reach
    still bounds it), even on a ring left with one fiber."""
    p = Params({"fibers.rings": rings, "fibers.fiber_radius": 0.5 / rings, "fibers.radial_jitter": 1.0,
                "fibers.angular_jitter": 1.0, "fibers.edge_density": density, "fibers.edge_width": width,
                "fibers.edge_thickness": max(density, 0.05), "fibers.phi_step": 20.0})
    lay = ring_layout(p)
    for name in ("rho", "dphi", "rot", "max_dr", "max_dphi", "reach"):
        assert np.isfinite(getattr(lay, name)).all(), name
    ring, j, cx, cy, _ = reference.all_fibers(lay, 3)
    r = np.hypot(cx, cy)
    half = 0.5 / rings
    assert (np.abs(r - lay.rho[ring]) <= half - lay.ring_radius[ring] + 1e-12).all()
    slot = lay.rot[ring] + j * lay.dphi[ring]
    off = np.angle(np.exp(1j * (np.arctan2(cy, cx) - slot)))
    assert (np.abs(off) <= lay.max_dphi[ring] + 1e-9).all()


@pytest.mark.parametrize("rings", [1, 3, 10, 64])
@pytest.mark.parametrize("thickness,width", [(0.4, 0.6), (0.05, 0.05), (0.05, 1.0), (1.0, 0.5)])
def test_profile_thins_the_outer_fibers(rings, thickness, width):
    """The outermost ring's fibers are edge_thickness of fiber_radius, the core's fiber_radius, linear in
    the ring's outer boundary between; the ring's jitter and reach follow its own radius."""
    rf = 0.4 / rings
    p = Params({"fibers.rings": rings, "fibers.fiber_radius": rf, "fibers.edge_thickness": thickness,
                "fibers.edge_width": width, "fibers.radial_jitter": 1.0})
    lay = ring_layout(p)
    ramp = np.clip(1.0 - (np.arange(rings) / rings) / width, 0.0, 1.0)
    want = rf * (1.0 - (1.0 - thickness) * ramp)
    np.testing.assert_allclose(lay.ring_radius, want, rtol=1e-12)
    assert lay.ring_radius[0] == pytest.approx(rf * thickness) and lay.fiber_radius == rf
    np.testing.assert_allclose(lay.max_dr, 0.5 / rings - lay.ring_radius, rtol=1e-12)
    assert (lay.reach >= lay.max_dphi).all() and np.isfinite(lay.reach).all()
    if thickness == 1.0:
        assert (lay.ring_radius == rf).all(), "the default thickness keeps every fiber at fiber_radius"


def test_profile_range_is_checked():
    with pytest.raises(ParamError, match="fibers.edge_density"):
        Params({"fibers.edge_density": 0.0})
    with pytest.raises(ParamError, match="fibers.edge_width"):
        Params({"fibers.edge_width": 0.0})
    with pytest.raises(ParamError, match="fibers.edge_thickness"):
        Params({"fibers.edge_thickness": 0.0})


# --------------------------------------------------------------------------------------------------
# The GLSL twin (the per-ring uniforms), against the reference and brute force
# --------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("change", [PROFILE, {"fibers.edge_density": 0.3}, {"fibers.edge_thickness": 0.3}],
                         ids=["all", "density", "thickness"])
def test_profile_changes_the_image(renderer, change):
    base = {"scene.count": 8, "scene.segments": 3, "fibers.phi_step": 3.0, "fibers.fiber_radius": 0.03}
    p, scene, cam = setup(renderer, base)
    before = renderer.render(p, cam, SIZE).color
    p2, _, cam2 = setup(renderer, {**base, **change})
    after = renderer.render(p2, cam2, SIZE).color
    changed = np.any(before != after, -1).mean()
    assert changed > 0.01, f"the profile changed only {changed:.4%} of the pixels"


PROFILE_SCENES = [
    ("single-side", {"scene.generator": "single", "scene.radius": 1.0, "scene.length": 4.0, **PROFILE},
     {"elevation": 0.0}),
    ("sparse-edge-jitter", {"scene.generator": "single", "scene.radius": 1.0, "scene.length": 3.0,
                            "fibers.edge_density": 0.02, "fibers.edge_width": 1.0, "fibers.radial_jitter": 1.0,
                            "fibers.angular_jitter": 1.0, "fibers.fiber_radius": 0.05}, {"elevation": 25.0}),
    ("tapered-bent", {"scene.count": 6, "scene.segments": 4, "scene.bend": 70.0, "scene.taper": 0.6,
                      "fibers.edge_density": 0.1, "fibers.edge_width": 0.05}, {"azimuth": 100.0}),
    ("grazing", {"scene.generator": "single", "scene.radius": 1.0, "scene.length": 1.0, "fibers.length_jitter": 0.0,
                 "fibers.edge_density": 0.05, "fibers.edge_thickness": 0.05, "fibers.phi_step": 2.0},
     {"elevation": 89.0}),
    ("thin-edge-thick-core", {"scene.generator": "single", "scene.radius": 1.0, "scene.length": 3.0,
                              "fibers.rings": 4, "fibers.fiber_radius": 0.12, "fibers.edge_thickness": 0.1,
                              "fibers.edge_width": 1.0, "fibers.phi_step": 8.0, "fibers.radial_jitter": 1.0},
     {"elevation": 10.0}),
    ("shaped", {"scene.generator": "single", "scene.radius": 1.0, "scene.length": 2.0, "fibers.rings": 5,
                "fibers.phi_step": 9.0, "fibers.fiber_radius": 0.06, "shape.curl_amplitude": 0.4,
                "shape.twist": 0.5, "shape.ellipsoid": 0.5, **PROFILE}, {"elevation": 20.0}),
]


@pytest.mark.parametrize("name,values,camera", PROFILE_SCENES, ids=[s[0] for s in PROFILE_SCENES])
def test_profile_exact_equals_brute_and_the_reference(renderer, name, values, camera):
    p, scene, cam = setup(renderer, values, camera)
    frames = {m: renderer.render(p, cam, SIZE, outputs=("ids", "geom"), mode=m) for m in ("exact", "fast", "brute")}
    exact, brute = frames["exact"], frames["brute"]
    assert exact.hit.sum() > 200, "the scene should show fibers"
    differ = np.any(exact.ids[..., :3] != brute.ids[..., :3], -1)
    assert differ.sum() == 0, f"{name}: {differ.sum()} pixels differ between exact and brute"
    assert (frames["fast"].hit == exact.hit).all(), "fast and exact must agree on coverage"
    for f in frames.values():
        assert np.isfinite(f.geom).all()
    ref = reference_ids(scene, p, cam, SIZE)
    got = gpu_ids(exact)
    hit = (ref[..., 0] > 0) | (got[..., 0] > 0)
    same = np.all(ref == got, -1)[hit]
    assert same.mean() >= 0.999, f"{(~same).sum()} of {hit.sum()} hit pixels disagree with float64"


# --------------------------------------------------------------------------------------------------
# The explicit baseline places and draws the same fibers
# --------------------------------------------------------------------------------------------------
def test_explicit_places_the_profiled_fibers():
    lay = reference.ring_layout(Params({"fibers.rings": 12, "fibers.radial_jitter": 1.0, **PROFILE}))
    guides = np.array([0, 5, 99])
    cx, cy, v_end, _, _ = fiber_centers(lay, guides)
    for gi, g in enumerate(guides):
        _, _, rx, ry, rv = reference.all_fibers(lay, int(g))
        np.testing.assert_array_equal(cx[gi], rx)
        np.testing.assert_array_equal(cy[gi], ry)
        np.testing.assert_array_equal(v_end[gi], rv)


def test_explicit_draws_the_profiled_fibers(ctx, renderer):
    p, scene, cam = setup(renderer, {"scene.count": 8, "fibers.phi_step": 3.0, "fibers.fiber_radius": 0.04,
                                     **PROFILE})
    virtual = renderer.render(p, cam, SIZE, outputs=("ids",), mode="exact")
    e = ExplicitRenderer(ctx)
    try:
        e.set_scene(scene, p)
        explicit = e.render(p, cam, SIZE, outputs=("ids",))
    finally:
        e.release()
        e.release_targets()
    # the floors of tests/test_explicit.py (ribbons against cylinders; why there)
    m = compare_frames(virtual, explicit)
    assert m["covered_virtual"] > 0.05, "the scene should show fibers"
    assert m["coverage_agree"] >= 0.995 and m["covered_iou"] >= 0.97 and m["id_agree"] >= 0.90, m


# --------------------------------------------------------------------------------------------------
# Grooms: clump size and taper
# --------------------------------------------------------------------------------------------------
def _groom(name: str, **values) -> Params:
    return Params({"scene.generator": "groom", "scene.groom_file": str(DATA / name), **values})


@needs_data
def test_groom_radius_scale_scales_every_container_and_defaults_to_today():
    from app.scene.grooms import scene_from_groom

    base = scene_from_groom(_groom("Bangs_100.hair"))
    same = scene_from_groom(_groom("Bangs_100.hair", **{"scene.groom_radius_scale": 1.0}))
    assert np.array_equal(base.segments, same.segments)
    big = scene_from_groom(_groom("Bangs_100.hair", **{"scene.groom_radius_scale": 1.5, "scene.segments": 3}))
    assert base.source.segments == 3, "the comparison needs the same segment count"
    np.testing.assert_allclose(big.segments[:, 3], 1.5 * base.segments[:, 3], rtol=1e-6)
    np.testing.assert_allclose(big.source.radii, 1.5 * base.source.radii)
    info = "\n".join(big.source_info())
    assert "1.5 x (0.75 x the median distance" in info and "scene.groom_radius_scale" in info


@needs_data
def test_groom_radius_scale_applies_to_clusters():
    from app.scene.grooms import scene_from_groom

    a = scene_from_groom(_groom("Curly_100.ply", **{"scene.groom_cluster": 20, "scene.segments": 8}))
    b = scene_from_groom(_groom("Curly_100.ply", **{"scene.groom_cluster": 20, "scene.segments": 8,
                                                    "scene.groom_radius_scale": 0.5}))
    np.testing.assert_allclose(b.source.radii, 0.5 * a.source.radii)


@needs_data
def test_taper_narrows_groom_containers_toward_the_tip():
    """scene.taper reaches groom containers: the last segment of every guide ends at (1 - taper) of its
    root radius, and vfiber info says so."""
    from app.scene.grooms import scene_from_groom

    s = scene_from_groom(_groom("Bangs_100.hair", **{"scene.taper": 0.6}))
    rows = s.segments
    guide = rows[:, 19].astype(np.int64)
    last = np.r_[guide[1:] != guide[:-1], True]
    first = np.r_[True, guide[1:] != guide[:-1]]
    np.testing.assert_allclose(rows[last, 7], 0.4 * rows[first, 3], rtol=1e-5)
    assert "scene.taper = 0.6" in "\n".join(s.source_info())


@needs_data
@pytest.mark.parametrize("values", [{"scene.groom_radius_scale": 1.6}, {"scene.taper": 0.7}, PROFILE])
def test_groom_controls_change_the_groom_image(renderer, values):
    from app.scene.grooms import scene_from_groom

    frames = []
    for v in ({}, values):
        p = _groom("sintel_hair.tfx", **v)
        scene = scene_from_groom(p)
        renderer.set_scene(scene)
        cam = Camera.from_params(_groom("sintel_hair.tfx"), scene_from_groom(_groom("sintel_hair.tfx")),
                                 aspect=SIZE[0] / SIZE[1])
        frames.append(renderer.render(p, cam, SIZE, outputs=("ids", "color")))
    changed = np.any(frames[0].color != frames[1].color, -1).mean()
    assert changed > 0.01, f"{values} changed only {changed:.4%} of the pixels"
    assert np.isfinite(frames[1].color).all()


# --------------------------------------------------------------------------------------------------
# The OSL twin: vf_ring computes the profiled layout in the shader (float32)
# --------------------------------------------------------------------------------------------------
from tests.export.test_osl_export import _probe, blender_test, gl_vs_cycles, same_fiber  # noqa: E402


OSL_PROFILES = [dict(PROFILE), {"fibers.edge_density": 0.02, "fibers.edge_width": 1.0, "fibers.rings": 64,
                                "fibers.phi_step": 0.7, "fibers.fiber_radius": 0.005, "fibers.edge_thickness": 0.05},
                {"fibers.edge_density": 0.37, "fibers.edge_width": 0.05, "fibers.rings": 3, "fibers.phi_step": 9.0,
                 "fibers.even_spacing": 1.0, "fibers.phi_increment": 2.0},
                {"fibers.edge_density": 0.5, "fibers.hash": "thesis", "fibers.rings": 5, "fibers.phi_step": 7.0}]


def test_the_export_carries_the_profile():
    from app.export import osl as X

    src = X.osl_source(Params(PROFILE))
    assert "float fibers_edge_density = 0.25" in src and "float fibers_edge_width = 0.6" in src
    assert "p.edgeDensity = fibers_edge_density;" in src and "p.edgeWidth = fibers_edge_width;" in src
    assert "float fibers_edge_thickness = 0.4" in src and "p.edgeThickness = fibers_edge_thickness;" in src


@blender_test
def test_profiled_layout_in_cycles_matches_reference(cycles, tmp_path):
    """Fibers per ring (exactly), rotation and reach of every ring of each profile, OSL against float64."""
    looks = [Params(v) for v in OSL_PROFILES]
    rows = [(li, i) for li, p in enumerate(looks) for i in range(p["fibers.rings"])]
    fields = {"rings": ("int", "fibers.rings"), "phiStep": ("float", "fibers.phi_step"),
              "phiIncrement": ("float", "fibers.phi_increment"), "evenSpacing": ("float", "fibers.even_spacing"),
              "edgeDensity": ("float", "fibers.edge_density"), "edgeWidth": ("float", "fibers.edge_width"),
              "edgeThickness": ("float", "fibers.edge_thickness"), "fiberRadius": ("float", "fibers.fiber_radius"),
              "radialJitter": ("float", "fibers.radial_jitter"),
              "angularJitter": ("float", "fibers.angular_jitter"), "seed": ("int", "fibers.seed")}
    arrays = {f"a_{f}": (t, [repr(float(looks[li][key])) if t == "float" else int(looks[li][key])
                             for li, _ in rows]) for f, (t, key) in fields.items()}
    arrays["a_thesis"] = ("int", [int(looks[li]["fibers.hash"] == "thesis") for li, _ in rows])
    arrays["a_ring"] = ("int", [i for _, i in rows])
    body = [f"    if (k < {len(rows)}) {{", "        VfParams p;"]
    body += [f"        p.{f} = a_{f}[k];" for f in fields]
    body += ["        p.thesisHash = a_thesis[k];", "        VfRing R;", "        vf_ring(p, a_ring[k], R);",
             "        value = color((float)R.n, R.fiberRadius, R.reach);", "    }"]
    got = _probe(cycles, tmp_path, "vf_profile_probe", arrays, "\n".join(body), len(rows))
    for li, p in enumerate(looks):
        lay = reference.ring_layout(p)
        sel = [k for k, (lj, _) in enumerate(rows) if lj == li]
        assert got[sel, 0].tolist() == lay.n.tolist(), f"{OSL_PROFILES[li]}: fibers per ring differ"
        assert lay.n[0] < ring_layout(p.replace(**{"fibers.edge_density": 1.0})).n[0]
        np.testing.assert_allclose(got[sel, 1], lay.ring_radius, rtol=1e-6, atol=1e-9)
        assert (got[sel, 2] >= lay.reach - 2e-6).all() and (got[sel, 2] <= lay.reach + 2e-3).all()


@blender_test
def test_profiled_fiber_ids_match_preview(cycles, renderer, tmp_path):
    """One container with a thinned edge: Cycles sees the same fiber as GL in (nearly) every pixel."""
    p = Params({"scene.generator": "single", "scene.radius": 0.3, "scene.length": 1.0, "fibers.rings": 5,
                "fibers.phi_step": 6.0, "fibers.fiber_radius": 0.08, "fibers.edge_density": 0.3,
                "fibers.edge_width": 0.7, "fibers.edge_thickness": 0.3, "camera.elevation": 25.0})
    r = gl_vs_cycles(cycles, renderer, p, tmp_path, "profile_ids", debug_view=1)
    both = r["gl"] & r["cycles"]
    same = same_fiber(r)
    assert both.sum() > 2000 and r["agree"] >= 0.995
    assert same[both].mean() >= 0.99, f"fiber ids agree on only {same[both].mean():.4%} of {both.sum()} px"


# --------------------------------------------------------------------------------------------------
# Per-groom defaults (fibers.groom_auto)
# --------------------------------------------------------------------------------------------------
SHARED = ("sintel_hair.tfx", "Bangs_100.hair", "Ratboy_mohawk.tfx", "harolongo.data", "Curly_100.ply")
AUTO_KEYS = ("fibers.rings", "fibers.phi_step", "fibers.phi_increment", "fibers.even_spacing",
             "fibers.fiber_radius", "fibers.edge_density", "fibers.edge_width")


@needs_data
def test_groom_auto_is_on_by_default_and_off_is_the_plain_fill():
    from app.params import BY_KEY
    from app.presets import resolve_params

    p, _ = resolve_params(str(DATA / "sintel_hair.tfx"))
    assert p["fibers.groom_auto"] and BY_KEY["fibers.groom_auto"].default is True
    assert p["fibers.rings"] == 7 and p["fibers.fiber_radius"] != BY_KEY["fibers.fiber_radius"].default
    off, _ = resolve_params(str(DATA / "sintel_hair.tfx"), ["fibers.groom_auto=false"])
    assert all(off[k] == BY_KEY[k].default for k in AUTO_KEYS)


@needs_data
@pytest.mark.parametrize("name", SHARED)
def test_groom_auto_fibers_are_a_pixel_or_less_and_fill_the_core(name):
    """Against the camera itself: at the default camera and 640x360 each fiber is 0.3 .. 1 px wide, or as
    wide as its ring allows; the core is opaque (about CORE_DEPTH fibers deep along a diameter, more for
    containers under SMALL_CONTAINER_PX in radius: core_depth)."""
    from app.presets import resolve_params
    from app.scene.grooms import defaults, scene_from_groom

    p, _ = resolve_params(str(DATA / name), ["fibers.groom_auto=true"])
    scene = scene_from_groom(p)
    cam = Camera.from_params(p, scene, aspect=640 / 360)
    pixel = 2.0 * np.linalg.norm(cam.position - cam.target) * np.tan(np.radians(cam.fov) / 2) / 360
    R = float(np.median(scene.source.radii))
    lay = ring_layout(p)
    width_px = 2.0 * lay.fiber_radius * R / pixel
    cap = defaults.MAX_RING_FILL * 0.5 / lay.rings
    assert 2 <= lay.rings <= 10
    assert 0.3 <= width_px <= 1.0 or (lay.fiber_radius == pytest.approx(cap) and width_px < 1.0), width_px
    # fibers per unit area in the core (the innermost rings, whole density) times the area a diameter sweeps
    core = slice(lay.rings // 2, lay.rings)
    area = 2.0 * np.pi * lay.rho[core] / lay.rings
    depth = float(lay.n[core].sum() / area.sum()) * 4.0 * lay.fiber_radius
    assert depth == pytest.approx(defaults.core_depth(R / pixel), rel=0.25)
    if lay.rings >= defaults.EDGE_MIN_RINGS:
        assert p["fibers.edge_density"] < 1


def test_small_containers_keep_the_fibers_per_pixel_of_a_two_pixel_one():
    from app.scene.grooms import defaults

    small = defaults.SMALL_CONTAINER_PX
    assert defaults.core_depth(small) == defaults.core_depth(20.0) == defaults.CORE_DEPTH
    # fibers of a fixed width in px: a container holds depth x r_px^2 of them, and their summed width per
    # pixel of its diameter (what pixel centres see when there is no opaque core) is depth x r_px / 2
    per_px = lambda ratio: defaults.core_depth(ratio) * ratio / 2
    for ratio in (1.5, 1.0, 0.5, 0.25):
        assert per_px(ratio) == pytest.approx(per_px(small))
    assert per_px(4.0) > per_px(small)                      # above it the core is opaque: depth alone counts
    # and the layout follows: at the same rings and fiber radius, a 1 px container gets twice the fibers per
    # unit area of a 2 px one (so half as many fibers in all, not a quarter)
    one = defaults.auto_fibers(1.0, 1.0, rings=2, fiber_radius=0.2)
    two = defaults.auto_fibers(2.0, 1.0, rings=2, fiber_radius=0.2)
    assert one["fibers.phi_step"] == pytest.approx(two["fibers.phi_step"] / 2, rel=1e-3)


@needs_data
def test_groom_auto_keeps_what_a_person_set():
    from app.presets import resolve_params

    auto, _ = resolve_params(str(DATA / "Bangs_100.hair"), ["fibers.groom_auto=true"])
    p, _ = resolve_params(str(DATA / "Bangs_100.hair"), ["fibers.groom_auto=true", "fibers.rings=4",
                                                         "fibers.edge_density=0.9"])
    assert p["fibers.rings"] == 4 and p["fibers.edge_density"] == 0.9
    assert p["fibers.fiber_radius"] <= 0.5 / 4 and p["fibers.phi_step"] != auto["fibers.phi_step"]
    assert p["fibers.even_spacing"] == auto["fibers.even_spacing"] == 1.0
    q, _ = resolve_params(str(DATA / "Bangs_100.hair"), ["fibers.groom_auto=true", "fibers.phi_step=2.5"])
    assert q["fibers.phi_step"] == 2.5 and q["fibers.rings"] == auto["fibers.rings"]


@needs_data
def test_groom_auto_leaves_a_preset_alone(tmp_path):
    """A preset lists every key, so all of them are a person's: the groom's defaults change nothing."""
    from app.presets import resolve_params, save_preset

    values = {"scene.generator": "groom", "scene.groom_file": str(DATA / "Curly_100.ply"), "fibers.groom_auto": True}
    path = tmp_path / "look.toml"
    save_preset(path, Params(values), "look")
    p, _ = resolve_params(str(path))
    assert p == Params(values)


@needs_data
def test_groom_auto_is_reported_by_info():
    from app.info import info_lines
    from app.presets import resolve_params
    from app.scene.grooms import scene_from_groom

    p, _ = resolve_params(str(DATA / "Ratboy_mohawk.tfx"), ["fibers.groom_auto=true", "fibers.rings=4"])
    lines = [x for x in info_lines(p, scene_from_groom(p), "x") if x.startswith("groom auto")]
    assert len(lines) == 1 and "px in radius at the default camera" in lines[0]
    assert lines[0].endswith("set by you, kept: fibers.rings = 4"), lines[0]
    p0, _ = resolve_params(str(DATA / "Ratboy_mohawk.tfx"))          # on by default: reported, nothing kept
    line = [x for x in info_lines(p0, scene_from_groom(p0), "x") if x.startswith("groom auto")]
    assert len(line) == 1 and "set by you" not in line[0] and "groom_children 0" in line[0], line
    off, _ = resolve_params(str(DATA / "Ratboy_mohawk.tfx"), ["fibers.groom_auto=false"])
    assert not [x for x in info_lines(off, scene_from_groom(off), "x") if x.startswith("groom auto")]


@needs_data
def test_groom_auto_in_the_viewer():
    from app.presets import resolve_params
    from app.viewer.state import AppState

    s = AppState()
    assert s.open_groom(DATA / "Curly_100.ply")
    # opened under the look on screen, as `vfiber view GROOM --preset default`: the look's fibers, the
    # groom's own scene (its interpolated children)
    under, _ = resolve_params(str(DATA / "Curly_100.ply"), look="default")
    assert s.params["fibers.rings"] == 10 and s.params["fibers.phi_step"] == 1.0
    assert s.params["scene.groom_children"] == under["scene.groom_children"] > 0
    assert s.edit("fibers.groom_auto", False) and s.edit("fibers.groom_auto", True)
    want, _ = resolve_params(str(DATA / "Curly_100.ply"))
    assert all(s.params[k] == want[k] for k in AUTO_KEYS)
    assert s.edit("fibers.rings", 6) and s.params["fibers.rings"] == 6      # a slider moved afterwards wins
    # more children: the fiber sliders follow the thinner containers, the children stay as set
    assert s.edit("scene.groom_children", 3) and s.params["scene.groom_children"] == 3
    assert s.params["fibers.rings"] == 10 and s.params["fibers.phi_step"] != want["fibers.phi_step"]


@needs_data
@pytest.mark.parametrize("name", ["sintel_hair.tfx", "Ratboy_mohawk.tfx"])
def test_groom_auto_exact_equals_brute(renderer, name):
    from app.presets import resolve_params
    from app.scene.grooms import scene_from_groom

    p, _ = resolve_params(str(DATA / name), ["fibers.groom_auto=true"])
    scene = scene_from_groom(p)
    renderer.set_scene(scene)
    cam = Camera.from_params(p, scene, aspect=SIZE[0] / SIZE[1])
    exact = renderer.render(p, cam, SIZE, outputs=("ids", "color", "geom"), mode="exact")
    brute = renderer.render(p, cam, SIZE, outputs=("ids",), mode="brute")
    assert exact.hit.mean() > 0.05
    assert (exact.ids[..., :3] == brute.ids[..., :3]).all()
    assert np.isfinite(exact.geom).all()
