"""The Blender/Cycles verification harness (app/export/blender.py).

Needs the [blender] extra (bpy==5.0.1); skipped with the reason otherwise. Compiling and querying run in this
process; every render runs in its own child process (~1.3 s each at these sizes, of which ~1 s is import bpy).
"""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from app.export import blender as B
from tests.support.paths import OSL_FIXTURES

FIX = OSL_FIXTURES

pytestmark = [
    pytest.mark.blender,
    pytest.mark.skipif(importlib.util.find_spec("bpy") is None,
                       reason="bpy is not installed: pip install 'vfiber[blender]' (bpy==5.0.1, Python 3.11)"),
]


@pytest.fixture(scope="module", autouse=True)
def _blender():
    ok, why = B.blender_available()
    if not ok:
        pytest.skip(f"Blender harness unavailable: {why}")


def iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / max(1, (a | b).sum()))


def mask(res) -> np.ndarray:
    return res["rgba"][..., 3] > 0.5


def albedo_fraction(res, albedo) -> float:
    """Fraction of fully covered pixels whose colour is ``albedo`` (to 1e-3)."""
    rgba = res["rgba"]
    solid = rgba[..., 3] > 0.999
    return float(np.isclose(rgba[solid][:, :3], albedo, atol=1e-3).all(axis=1).mean())


# two containers with different frames: one along world X, one tilted
CYLS = [((-1.6, 0.0, 0.5), (0.4, 0.0, 0.5), 0.3),
        ((0.8, 0.2, -0.9), (1.4, -0.3, 0.9), 0.3)]
CAM = dict(position=(0.0, -6.0, 0.3), target=(0.0, 0.0, 0.0), up=(0, 0, 1), fov_deg=35.0)


# ---------------------------------------------------------------------------------------------------- compile


def test_available_reports_versions():
    ok, why = B.blender_available()
    assert ok and "bpy 5.0" in why and "OSL" in why


def test_compile_fixture(tmp_path):
    oso = tmp_path / "object_half.oso"
    B.compile_osl(FIX / "object_half.osl", oso)
    text = oso.read_text()
    assert text.startswith("OpenShadingLanguage") and "object_half" in text


def test_broken_fixture_names_the_line(tmp_path):
    with pytest.raises(B.OSLCompileError) as ei:
        B.compile_osl(FIX / "broken.osl", tmp_path / "broken.oso")
    e = ei.value
    assert e.lines == [6]
    assert "broken.osl:6" in str(e) and "not_declared_anywhere" in str(e)
    assert not (tmp_path / "broken.oso").exists()


def test_compile_missing_source(tmp_path):
    with pytest.raises(B.OSLCompileError, match="not found"):
        B.compile_osl(tmp_path / "nope.osl", tmp_path / "nope.oso")


def test_query_parameters_and_metadata(tmp_path):
    oso = tmp_path / "object_half.oso"
    B.compile_osl(FIX / "object_half.osl", oso)
    q = B.query_osl(oso)
    assert q["name"] == "object_half" and q["type"] == "shader"
    assert q["metadata"]["help"].startswith("vfiber harness fixture")
    p = q["parameters"]
    assert list(p) == ["axis", "cut", "albedo", "BSDF"]  # declaration order
    assert p["axis"]["type"] == "int" and p["axis"]["default"] == 0
    assert p["axis"]["metadata"] == {"label": "Axis", "min": 0, "max": 2,
                                     "help": "object-space axis to cut along: 0 = x, 1 = y, 2 = z "
                                             "(the cylinder axis)"}
    assert p["cut"]["type"] == "float" and p["cut"]["metadata"]["min"] == -100.0
    assert p["albedo"]["type"] == "color" and p["albedo"]["default"] == pytest.approx([0.8] * 3)
    assert p["BSDF"] == {"name": "BSDF", "type": "closure color", "default": None, "output": True,
                         "closure": True, "arraylen": 0, "metadata": {}}
    assert B.query_osl(FIX / "object_half.osl")["parameters"].keys() == p.keys()  # .osl is compiled first


def test_query_unreadable(tmp_path):
    bad = tmp_path / "junk.oso"
    bad.write_text("not bytecode\n")
    with pytest.raises(B.OSLQueryError):
        B.query_osl(bad)


# ----------------------------------------------------------------------------------------------------- render


def test_object_space_cut_inside_cycles():
    """transparent() where an object-space coordinate exceeds a cut: the mask is the part of each cylinder on
    the kept side *in its own frame*, which only works if transform("object", P) is per object in Cycles."""
    size = (256, 256)
    full = B.render_cylinders_with_osl(FIX / "object_half.osl", CYLS, CAM, size, params={"axis": 2, "cut": 1e3})
    along = B.render_cylinders_with_osl(FIX / "object_half.osl", CYLS, CAM, size, params={"axis": 2, "cut": 1.0})
    across = B.render_cylinders_with_osl(FIX / "object_half.osl", CYLS, CAM, size, params={"axis": 0, "cut": 0.0})
    m_full, m_along, m_across = mask(full), mask(along), mask(across)

    ref_full = B.analytic_cylinder_mask(CYLS, CAM, size)
    assert m_full.sum() > 2000
    assert iou(m_full, ref_full) > 0.98
    for m in (m_along, m_across):
        assert m.any()
        assert 0.3 < m.sum() / m_full.sum() < 0.7  # roughly half of the silhouette ...
        assert (m & ~m_full).sum() < 0.01 * m_full.sum()  # ... and inside it

    # ... and exactly the half predicted in each cylinder's own frame (origin p0, +Z to p1, +X orthonormal_x)
    ref_along = B.analytic_cylinder_mask(CYLS, CAM, size, keep=lambda q, i: q[..., 2] <= 1.0)
    ref_across = B.analytic_cylinder_mask(CYLS, CAM, size, keep=lambda q, i: q[..., 0] <= 0.0)
    assert iou(m_along, ref_along) > 0.97
    assert iou(m_across, ref_across) > 0.97
    # a world-space cut would give a different picture
    assert iou(m_along, B.analytic_cylinder_mask(CYLS, CAM, size, keep=lambda q, i: q[..., 0] <= 0.0)) < 0.8

    # the surfaces show the diffuse albedo (uniform white world, a lone convex object: exactly 0.8 per sample);
    # samples whose bounce hits the other cylinder are dark (diffuse_bounces=1) and, in the cut render, pixels
    # that look through the cut into the inside of the kept part
    assert albedo_fraction(full, 0.8) > 0.8
    assert albedo_fraction(along, 0.8) > 0.8
    assert full["seconds"] < 20


def test_camera_matches_opengl_pinhole():
    """An opaque, tilted, capped cylinder through a non-square, rolled camera against the numpy pinhole."""
    size = (320, 192)
    cyl = [((-0.9, 0.3, -0.4), (1.1, -0.2, 0.7), 0.35)]
    cam = dict(position=(1.5, -4.0, 2.0), target=(0.1, 0.0, 0.1), up=(0.25, 0.0, 1.0), fov_deg=30.0)
    res = B.render_cylinders_with_osl(FIX / "opaque.osl", cyl, cam, size, segments=64)
    assert res["rgba"].shape == (192, 320, 4) and res["rgba"].dtype == np.float32
    m, ref = mask(res), B.analytic_cylinder_mask(cyl, cam, size)
    assert ref.sum() > 3000
    assert iou(m, ref) > 0.98
    assert (m == ref).mean() > 0.995
    # no sub-pixel shift either: centroids agree to a fraction of a pixel
    cy, cx = np.argwhere(m).mean(0)
    ry, rx = np.argwhere(ref).mean(0)
    assert abs(cx - rx) < 0.3 and abs(cy - ry) < 0.3


def test_params_set_sockets_and_colour():
    res = B.render_cylinders_with_osl(FIX / "opaque.osl", CYLS[:1], CAM, (96, 96), samples=4,
                                      params={"albedo": (0.2, 0.4, 0.6)})
    assert res["sockets"]["albedo"] == pytest.approx([0.2, 0.4, 0.6, 1.0])
    assert (res["rgba"][..., 3] > 0.999).sum() > 100
    assert albedo_fraction(res, (0.2, 0.4, 0.6)) > 0.97
    assert res["errors"] == []
    with pytest.raises(ValueError, match="no input parameter 'albeedo'"):
        B.render_cylinders_with_osl(FIX / "opaque.osl", CYLS[:1], CAM, (32, 32), params={"albeedo": 1.0})


def test_deterministic():
    a = B.render_cylinders_with_osl(FIX / "object_half.osl", CYLS, CAM, (64, 64), samples=4)
    b = B.render_cylinders_with_osl(FIX / "object_half.osl", CYLS, CAM, (64, 64), samples=4)
    assert np.array_equal(a["rgba"], b["rgba"])


def test_cycles_osl_conventions():
    """I points toward the viewer, getattribute sees the harness's mesh attributes, object frame = (p0, axis)."""
    p0, p1, r = CYLS[1]
    axis = np.subtract(p1, p0)
    res = B.render_cylinders_with_osl(FIX / "conventions.osl", [CYLS[1]], CAM, (96, 96), samples=1,
                                      params={"axis": tuple(axis / np.linalg.norm(axis)), "origin": p0,
                                              "radius": r, "cyl_length": float(np.linalg.norm(axis))})
    rgba = res["rgba"]
    solid = rgba[..., 3] > 0.999
    assert solid.sum() > 50
    red, green, blue = (rgba[solid][:, k].mean() for k in range(3))
    assert red == pytest.approx(1.0), "I does not point toward the viewer"
    assert green == pytest.approx(1.0), "getattribute('vf_radius'/'vf_length') failed"
    assert blue == pytest.approx(1.0), "object frame is not (p0, +Z along the axis)"


def test_unsupported_closure_is_an_error_in_strict_mode():
    with pytest.raises(B.BlenderRenderError, match="transparent_bsdf"):
        B.render_cylinders_with_osl(FIX / "unsupported.osl", CYLS[:1], CAM, (32, 32), samples=1)


def test_render_reports_compile_errors():
    with pytest.raises(B.OSLCompileError) as ei:
        B.render_cylinders_with_osl(FIX / "broken.osl", CYLS[:1], CAM, (32, 32))
    assert ei.value.lines == [6]


def test_analytic_reference_self_consistent():
    """Pure numpy: the reference camera puts the target at the image centre and respects the vertical fov."""
    cam = dict(position=(0, -5, 0), target=(0, 0, 0), up=(0, 0, 1), fov_deg=40.0)
    o, d = B.pinhole_rays(cam, (201, 100))
    assert d.shape == (100, 201, 3)
    # top-centre and bottom-centre rays span the vertical fov (pixel centres: just inside)
    top, bottom = d[0, 100], d[-1, 100]
    ang = np.degrees(np.arccos(np.dot(top, bottom)))
    assert ang == pytest.approx(2 * np.degrees(np.arctan(0.99 * np.tan(np.radians(20.0)))), abs=1e-6)
    assert top[2] > 0 > bottom[2]  # row 0 is the top
    # a cylinder on the view axis is centred
    m = B.analytic_cylinder_mask([((0, 0, -1), (0, 0, 1), 0.5)], cam, (201, 100))
    ys, xs = np.nonzero(m)
    assert xs.mean() == pytest.approx(100, abs=0.01) and ys.mean() == pytest.approx(49.5, abs=0.01)
