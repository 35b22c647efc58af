"""`vfiber export-blend`: a .blend that Cycles renders with the preview's fibers (app/export/blend.py).

The proxy-mesh geometry and the command line's errors are tested without Blender. With the [blender] extra
(bpy==5.0.1) every bundled preset and three real grooms are exported at 192x108, the file is opened and
rendered by a process that imports only bpy (app/export/render_blend.py, as a render farm would), and the
render is compared with `vfiber render --output id` at the same size: the coverage (alpha > 0.5 against
the GL hit mask) and the fiber ids (the shader's debug view: ring, fiber, guide + 1, one ray per pixel).
About 2-4 s per scene on 2 cores; Ratboy_mohawk (22,190 segments) about 20 s.
"""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from app import cli
from app.export import blend as XB
from app.presets import bundled_presets
from tests.support.paths import HAIR_DATA, ROOT

HAIR = HAIR_DATA
SIZE = "192x108"
HAS_BPY = importlib.util.find_spec("bpy") is not None
blender_test = pytest.mark.skipif(not HAS_BPY, reason="bpy is not installed: pip install 'vfiber[blender]' "
                                                      "(bpy==5.0.1, Python 3.11)")


# ------------------------------------------------------------------------------------------ proxy mesh


def _bent_scene():
    from app.params import Params
    from app.scene.generators import build_scene

    return build_scene(Params({"scene.generator": "curved", "scene.count": 3, "scene.segments": 6,
                               "scene.bend": 120.0, "scene.taper": 0.5}))


def _faces(verts, faces, sizes):
    out, o = [], 0
    for s in sizes:
        out.append(verts[faces[o:o + s]].astype(np.float64))
        o += s
    return out


def test_prisms_enclose_their_containers_with_joint_planes():
    """Points on each round, tapered container surface clipped by its joint planes lie inside its prism
    (every face plane has them behind it), and the prism is closed and outward facing."""
    from app import reference

    scene = _bent_scene()
    assert scene.n_segments >= 12
    verts, faces, sizes, rows = XB.container_boxes(scene.segments)
    sides = XB.PRISM_SIDES
    assert len(sizes) == scene.n_segments * (sides + 2)
    assert (rows == np.repeat(np.arange(scene.n_segments), sides + 2)).all()
    polys = _faces(verts, faces, sizes)
    rng = np.random.default_rng(1)
    for k, row in enumerate(scene.segments):
        seg = reference.segment(row)
        # surface points of the container: z in the slab, angle anywhere, radius w(z), kept if inside both joints
        z = rng.uniform(seg.z_lo, seg.z_hi, 4000)
        a = rng.uniform(0, 2 * np.pi, 4000)
        w = seg.r0 + seg.kappa * z
        local = np.stack([w * np.cos(a), w * np.sin(a), z], 1)
        # (and inside the bounding cylinder of radius r_bound, which clips the GL's container too where a
        # tapered container widens past its root below a leaning joint plane)
        keep = (local @ seg.n0 >= 0) & ((local - [0, 0, seg.h]) @ seg.n1 <= 0) & (w <= seg.r_bound)
        assert keep.sum() > 1000
        world = seg.p0 + local[keep] @ np.stack([seg.ex, seg.ey, seg.ez])
        centre = world.mean(0)
        for poly in polys[k * (sides + 2):(k + 1) * (sides + 2)]:
            n = np.cross(poly[1] - poly[0], poly[2] - poly[0])
            n /= np.linalg.norm(n)
            assert np.dot(n, poly.mean(0) - centre) > 0, "face not outward"
            assert ((world - poly[0]) @ n <= 1e-6 * seg.r0).all(), f"segment {k}: container pokes through its prism"


def test_prisms_of_one_guide_meet_at_the_joints():
    """Mitred ends: consecutive prisms overlap by no more than the margin along the axis (a slab box would
    reach a radius times the joint's slope into its neighbour)."""
    scene = _bent_scene()
    verts, faces, sizes, rows = XB.container_boxes(scene.segments)
    sides = XB.PRISM_SIDES
    seg = scene.segments.astype(np.float64)
    v = verts.reshape(len(seg), 2 * sides, 3).astype(np.float64)
    for k in range(len(seg) - 1):
        if seg[k, 19] != seg[k + 1, 19]:
            continue
        joint, n = seg[k, 4:7], seg[k, 12:15]
        reach_into_next = ((v[k] - joint) @ n).max()       # how far prism k passes the joint plane
        reach_into_prev = (-(v[k + 1] - joint) @ n).max()
        r = max(seg[k, 3], seg[k, 7])
        assert reach_into_next <= 2 * XB.BOX_MARGIN * r + 1e-6
        assert reach_into_prev <= 2 * XB.BOX_MARGIN * r + 1e-6


def test_face_attributes_carry_the_segment_rows():
    scene = _bent_scene()
    _, _, _, rows = XB.container_boxes(scene.segments)
    for name, cols in XB.ATTRIBUTES.items():
        a = XB._face_attribute(scene.segments, rows, cols)
        for j, c in enumerate(cols):
            want = scene.segments[rows, c] if c is not None else 0.0
            np.testing.assert_array_equal(a[:, j], want, err_msg=name)


def _dense_scene():
    """Bent, tapered guides packed closer than their width: every prism has neighbours of other guides."""
    from app.params import Params
    from app.scene.generators import build_scene

    return build_scene(Params({"scene.generator": "curved", "scene.count": 24, "scene.segments": 5,
                               "scene.bend": 90.0, "scene.taper": 0.4}))


def test_neighbour_lists_equal_a_brute_force_overlap_check():
    """The grid's lists are exactly the pairs whose capsules overlap, every pair tested (the prism's capsule
    against the other container's), deepest first, adjacent segments of one guide left out."""
    scene = _dense_scene()
    seg = scene.segments.astype(np.float64)
    n = len(seg)
    lists, counts = XB.neighbour_lists(seg, cap=XB.NEIGHBOUR_SLOTS[-1])
    (ap, bp, rp), (ac, bc, rc) = XB.overlap_capsules(seg)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    i, j = i.ravel(), j.ravel()
    depth = rp[i] + rc[j] - XB.segment_distance(ap[i], bp[i], ac[j], bc[j])
    adjacent = (seg[i, 19] == seg[j, 19]) & (np.abs(i - j) == 1)
    overlap = (depth >= 0) & (i != j) & ~adjacent
    assert counts.max() >= 4 and counts.sum() > n, "the scene should overlap: the test would say nothing"
    for z in range(n):
        want = j[(i == z) & overlap]
        want = want[np.argsort(-depth[z * n + want], kind="stable")]
        assert counts[z] == len(want)
        got = lists[z][lists[z] >= 0]
        assert sorted(got) == sorted(want), f"segment {z}"
        np.testing.assert_allclose(depth[z * n + got], depth[z * n + want])     # deepest first (ties aside)
    capped, _ = XB.neighbour_lists(seg, cap=2)
    np.testing.assert_array_equal(capped, lists[:, :2])


def test_every_container_reaching_into_a_prism_is_its_neighbour():
    """Points sampled inside each container (round, tapered, clipped by its joint planes): wherever one lies
    inside another segment's prism, that container is in the prism's neighbour list (or is the prism's own
    segment or a joint neighbour of it, which meets the prism only in its joint margin)."""
    from app import reference

    scene = _dense_scene()
    seg = scene.segments.astype(np.float64)
    n = len(seg)
    lists, _ = XB.neighbour_lists(seg)
    verts, faces, sizes, _ = XB.container_boxes(seg)
    polys = _faces(verts, faces, sizes)
    sides = XB.PRISM_SIDES
    planes = []                                                  # per prism: (faces, 3) normals, (faces,) offsets
    for z in range(n):
        ps = polys[z * (sides + 2):(z + 1) * (sides + 2)]
        nrm = np.array([np.cross(q[1] - q[0], q[2] - q[0]) for q in ps])
        nrm /= np.linalg.norm(nrm, axis=1)[:, None]
        planes.append((nrm, np.einsum("fk,fk->f", nrm, np.array([q[0] for q in ps]))))
    rng = np.random.default_rng(3)
    reached = 0
    for y in range(n):
        g = reference.segment(seg[y])
        z_loc = rng.uniform(g.z_lo, g.z_hi, 3000)
        w = (g.r0 + g.kappa * z_loc) * np.sqrt(rng.uniform(0, 1, 3000))
        a = rng.uniform(0, 2 * np.pi, 3000)
        local = np.stack([w * np.cos(a), w * np.sin(a), z_loc], 1)
        keep = (local @ g.n0 >= 0) & ((local - [0, 0, g.h]) @ g.n1 <= 0) & (w <= g.r_bound)
        world = g.p0 + local[keep] @ np.stack([g.ex, g.ey, g.ez])
        for z in range(n):
            if z == y or (seg[z, 19] == seg[y, 19] and abs(z - y) == 1):
                continue
            nrm, off = planes[z]
            if ((world @ nrm.T - off) <= 0).all(1).any():
                reached += 1
                assert y in lists[z], f"container {y} reaches into prism {z} but is not its neighbour"
    assert reached > n


def test_neighbour_slots_follow_the_counts_within_the_budget():
    counts = np.array([0, 1, 2, 3, 5, 9, 40, 64, 200])
    np.testing.assert_array_equal(XB.slot_bucket(counts), [0, 2, 2, 4, 8, 12, 48, 64, 64])
    assert XB.neighbour_cap(counts) == XB.NEIGHBOUR_SLOTS[-1]
    assert XB.neighbour_cap(np.full(10_000, 300), budget=10_000 * 8) == 8
    assert XB.neighbour_cap(np.full(10_000, 300), budget=10) == 0
    # the shader reads at most as many slots as the exporter writes
    osl = (ROOT / "osl" / "stages" / "segment.osl").read_text()
    assert f"#define VF_MAX_NEIGHBOURS {XB.NEIGHBOUR_SLOTS[-1]}\n" in osl


def test_neighbour_attributes_carry_the_neighbours_rows():
    scene = _dense_scene()
    seg = scene.segments
    lists, _ = XB.neighbour_lists(seg)
    _, _, _, rows = XB.container_boxes(seg)
    attrs = dict(XB.neighbour_face_attributes(seg, rows, lists, 4))
    assert len(attrs) == 4 * len(XB.ATTRIBUTES)
    for k in range(4):
        j = lists[rows, k]
        for name, cols in XB.ATTRIBUTES.items():
            a = attrs[XB.neighbour_attribute(k, name)]
            assert (a[j < 0] == 0).all()                 # an empty slot: radius 0 ends the list in the shader
            np.testing.assert_array_equal(a[j >= 0], XB._face_attribute(seg, j[j >= 0], cols), err_msg=name)


# ---------------------------------------------------------------------------------------- command line


def test_export_blend_without_bpy_says_what_to_install(tmp_path, monkeypatch, capsys):
    from app.export import blender as B

    def missing():
        raise B.BlenderUnavailable("no bpy")

    monkeypatch.setattr(B, "_bpy", missing)
    assert cli.main(["export-blend", "default", "-o", str(tmp_path / "x.blend")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "pip install 'vfiber[blender]'" in err and "bpy==5.0.1" in err
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("argv, part", [
    (["export-blend", "default", "-o", "x.png"], "ends in .blend"),
    (["export-blend", "default", "-o", "/nonexistent-folder/x.blend"], "does not exist"),
    (["export-blend", "default", "--size", "12"], "WIDTHxHEIGHT"),
    (["export-blend", "no-such-preset"], "no-such-preset"),
])
def test_export_blend_errors_are_one_line(argv, part, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert cli.main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and part in err


def test_export_osl_of_a_groom_points_to_export_blend(tmp_path, capsys):
    groom = HAIR / "sintel_hair.tfx"
    if not groom.exists():
        pytest.skip(f"{groom} not present")
    assert cli.main(["export-osl", str(groom), "-o", str(tmp_path / "x.osl")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "vfiber export-blend" in err and "UTF-8" not in err
    assert not list(tmp_path.iterdir())


# ----------------------------------------------------------------------------------------- with Blender


def _export(target: str, out: Path, *sets: str) -> str:
    code = "import sys; from app.cli import main; sys.exit(main(sys.argv[1:]))"
    extra = [a for s in sets for a in ("--set", s)]
    proc = subprocess.run([sys.executable, "-c", code, "export-blend", target, "-o", str(out), "--size", SIZE, *extra],
                          capture_output=True, text=True, cwd=str(ROOT), timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return proc.stdout


def _render_like_a_farm(blend: Path, out: Path, *extra: str) -> dict:
    """Render with a process that imports only bpy, from another folder, with no PYTHONPATH (-I)."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    script = ROOT / "app" / "export" / "render_blend.py"
    proc = subprocess.run([sys.executable, "-I", str(script), str(blend), str(out), *extra],
                          capture_output=True, text=True, cwd=str(out.parent), env=env, timeout=900)
    assert proc.returncode == 0, (proc.stdout + proc.stderr)[-3000:]
    errors = [ln for ln in (proc.stdout + proc.stderr).splitlines() if "ERROR" in ln]
    assert not errors, errors
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _gl_ids(target: str, out: Path) -> np.ndarray:
    assert cli.main(["render", target, "--size", SIZE, "--output", "id", "-o", str(out)]) == 0
    return np.load(out)


def agreement(cycles_rgba: np.ndarray, gl_ids: np.ndarray) -> tuple[float, float, int]:
    """(coverage agreement over all pixels, same (guide, ring, fiber) on pixels both cover, pixels both cover)."""
    covered_c = cycles_rgba[..., 3] > 0.5
    covered_g = gl_ids[..., 0] > 0
    both = covered_c & covered_g
    ids_c = np.rint(cycles_rgba[..., [2, 0, 1]]).astype(np.int64)     # emitted (ring, fiber, guide + 1)
    same = (ids_c[both] == gl_ids[..., :3][both].astype(np.int64)).all(1)
    return float((covered_c == covered_g).mean()), float(same.mean()) if both.any() else 1.0, int(both.sum())


TARGETS = [pr.name for pr in bundled_presets()] + [f"groom:{n}" for n in ("sintel_hair.tfx", "Bangs_100.hair",
                                                                          "Ratboy_mohawk.tfx")]


def _target(name: str) -> str:
    if name.startswith("groom:"):
        path = HAIR / name.split(":", 1)[1]
        if not path.exists():
            pytest.skip(f"{path} not present")
        return str(path)
    return name


@blender_test
@pytest.mark.blender
@pytest.mark.parametrize("name", TARGETS)
def test_exported_blend_renders_the_preview_fibers(name, tmp_path, record_property):
    target = _target(name)
    blend = tmp_path / "scene.blend"
    said = _export(target, blend)
    assert "container segments" in said and blend.stat().st_size > 0
    info = _render_like_a_farm(blend, tmp_path / "ids.npy", "--ids")
    # self-contained: no external file, the shader an internal text with its bytecode saved in the node
    assert info["external_paths"] == []
    assert [s["mode"] for s in info["scripts"]] == ["INTERNAL"]
    assert info["scripts"][0]["text_is_internal"] and info["scripts"][0]["filepath"] == ""
    assert info["scripts"][0]["bytecode"] > 1000
    assert info["size"] == [192, 108]
    cycles_rgba = np.load(tmp_path / "ids.npy")
    gl = _gl_ids(target, tmp_path / "gl.npy")
    coverage, same_id, both = agreement(cycles_rgba, gl)
    record_property("coverage", coverage)
    record_property("same_id", same_id)
    print(f"\n{name}: coverage agreement {coverage:.4%}, same id {same_id:.4%} of {both} pixels, "
          f"Cycles {info['seconds']:.2f} s, peak {info['peak_rss_bytes'] / 2**20:.0f} MiB")
    assert both > 500, "the scene is barely visible: the comparison would say nothing"
    assert coverage >= 0.97
    assert same_id >= 0.95


def _crossing_groom(path: Path) -> Path:
    """Two straight strands crossing at right angles, one a fiber's breadth above the other (.data format):
    over the crossing a ray often enters one container's prism first while the other has the nearer fiber."""
    import struct

    line = np.linspace(-1.0, 1.0, 5)[:, None]
    strands = [line * [1.0, 0.0, 0.0], line * [0.0, 1.0, 0.0] + [0.0, 0.0, 0.02]]
    data = struct.pack("<i", len(strands))
    for st in strands:
        data += struct.pack("<i", len(st)) + np.asarray(st, "<f4").tobytes()
    path.write_bytes(data)
    return path


@blender_test
@pytest.mark.blender
def test_crossing_containers_show_the_nearer_fiber(tmp_path):
    """Where two containers cross, Cycles shows the nearer fiber of the two, as the preview does, and not
    the fiber of the container whose prism the ray enters first (which the export did before neighbour
    lists: 77 % of the covered pixels agreed)."""
    target = str(_crossing_groom(tmp_path / "crossing.data"))
    _export(target, tmp_path / "scene.blend")
    _render_like_a_farm(tmp_path / "scene.blend", tmp_path / "ids.npy", "--ids")
    cycles_rgba = np.load(tmp_path / "ids.npy")
    gl = _gl_ids(target, tmp_path / "gl.npy")
    coverage, same_id, both = agreement(cycles_rgba, gl)
    guides = set(np.unique(np.rint(cycles_rgba[..., 2][cycles_rgba[..., 3] > 0.5])).astype(int).tolist())
    assert guides == {1, 2} and both > 1000
    assert coverage >= 0.99
    assert same_id >= 0.99


@blender_test
@pytest.mark.blender
@pytest.mark.parametrize("name", ["default", "twisted-curled-1", "groom:sintel_hair.tfx"])
def test_exact_mode_equals_brute_force_in_cycles(name, tmp_path):
    """The OSL traversal's candidate windows miss nothing: exact mode names the same fiber as testing every
    fiber of every ring, in every pixel (straight, curved and bent-groom containers)."""
    target = _target(name)
    ids = {}
    for mode in ("exact", "brute"):
        _export(target, tmp_path / f"{mode}.blend", f"quality.mode={mode}")
        _render_like_a_farm(tmp_path / f"{mode}.blend", tmp_path / f"{mode}.npy", "--ids")
        ids[mode] = np.load(tmp_path / f"{mode}.npy")
    assert (ids["exact"][..., 3] > 0.5).sum() > 1000
    assert np.array_equal(ids["exact"], ids["brute"])


@blender_test
@pytest.mark.blender
def test_shaded_render_is_lit_and_transparent_where_empty(tmp_path):
    """The file's own settings (64 adaptive samples, the key light, the world): fibers come out lit (not
    black: OSL ran, the closures are supported), the background is transparent film."""
    blend = tmp_path / "scene.blend"
    _export("curly-1", blend)
    info = _render_like_a_farm(blend, tmp_path / "shaded.npy", "--samples", "4")
    rgba = np.load(tmp_path / "shaded.npy")
    covered = rgba[..., 3] > 0.5
    assert covered.sum() > 500 and (rgba[..., 3] < 0.01).sum() > 5000
    assert rgba[covered][:, :3].mean() > 0.05
    assert info["samples"] == 4


# ------------------------------------------------------------------------------------ lights (issue 19)

LIGHT_SETS = ("light.fill_intensity=0.6", "light.fill_azimuth=-100", "light.rim_intensity=1.5",
              "light.rim_color=1.0,0.5,0.25", "light.rig_rotation=20", "light.environment=studio",
              "light.environment_rotation=35", "light.environment_intensity=0.7")

#: opens a .blend with nothing but bpy (as a farm would) and prints its lamps and world as one JSON line
_INSPECT = r"""
import json, os, re, sys, bpy
bpy.ops.wm.open_mainfile(filepath=os.path.abspath(sys.argv[1]))
lamps = []
for ob in bpy.data.objects:
    if ob.type == "LIGHT":
        toward = ob.matrix_world.to_3x3() @ __import__("mathutils").Vector((0, 0, 1))
        lamps.append({"name": ob.name, "type": ob.data.type, "direction": list(toward),
                      "rgb": [ob.data.energy * c for c in ob.data.color]})
nodes = bpy.context.scene.world.node_tree.nodes
env = nodes.get("vfiber environment")
images = [{"name": im.name, "packed": im.packed_file is not None, "filepath": im.filepath_raw,
           "packed_paths": [pf.filepath for pf in im.packed_files],
           "size": list(im.size)} for im in bpy.data.images if im.type == "IMAGE"]
bytecodes = [n.bytecode for m in bpy.data.materials if m.node_tree for n in m.node_tree.nodes
             if n.bl_idname == "ShaderNodeScript"]
out = {"lamps": lamps, "images": images, "external_paths": sorted(bpy.utils.blend_paths(absolute=False)),
       "bytecode_paths": sorted({p for b in bytecodes for p in re.findall(r"(?:^|[\s\"'=-])(/[\w.-]+/[\w./-]+)", b)}),
       "bytecodes": len(bytecodes),
       "env_image": env.image.name if env and env.image else None,
       "rotation": list(nodes["vfiber environment rotation"].inputs["Rotation"].default_value) if env else None,
       "mapping": nodes["vfiber environment rotation"].vector_type if env else None,
       "strength": nodes["vfiber environment light"].inputs["Strength"].default_value if env else None}
print(json.dumps(out)); sys.stdout.flush(); os._exit(0)
"""


def _inspect_like_a_farm(blend: Path) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    proc = subprocess.run([sys.executable, "-I", "-c", _INSPECT, str(blend)], capture_output=True, text=True,
                          cwd=str(blend.parent), env=env, timeout=300)
    assert proc.returncode == 0, (proc.stdout + proc.stderr)[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _blend_bytes(blend: Path) -> bytes:
    """The file's bytes, unpacked from Blender's zstd compression when there is the module for it."""
    data = blend.read_bytes()
    if data[:4] == b"\x28\xb5\x2f\xfd":
        zstd = pytest.importorskip("zstandard")
        data = zstd.ZstdDecompressor().decompressobj().decompress(data)
    return data


def _angle_degrees(a, b) -> float:
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    c = a @ b / np.linalg.norm(a) / np.linalg.norm(b)
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


@blender_test
@pytest.mark.blender
def test_exported_lights_match_the_light_rig(tmp_path):
    """Key, fill and rim come out as Sun lamps from light_rig's directions (within 1 degree) with 0.8 pi
    times its linear RGB (the key Sun's convention); the environment is the world's packed image, turned
    by light_rig's rotation and scaled by its strength; nothing in the file points outside it."""
    from app.render import look
    from app.render.environment import environment_image

    blend = tmp_path / "lit.blend"
    _export("default", blend, *LIGHT_SETS)
    params, _ = cli.resolve_params("default", list(LIGHT_SETS))
    rig = look.light_rig(params)
    assert [x["kind"] for x in rig["lights"]] == ["key", "fill", "rim"]
    info = _inspect_like_a_farm(blend)
    lamps = {x["name"]: x for x in info["lamps"]}
    assert len(lamps) == 3
    for light in rig["lights"]:
        lamp = lamps[f"vfiber {light['kind']} light"]
        assert lamp["type"] == "SUN"
        assert _angle_degrees(lamp["direction"], light["direction"]) < 1.0, light["kind"]
        np.testing.assert_allclose(lamp["rgb"], XB.SUN_PER_INTENSITY * np.asarray(light["color"]), rtol=1e-5,
                                   err_msg=light["kind"])
    assert info["external_paths"] == []
    # nor in the saved shader: oslc's comments and hints named the temporary files and Blender's folder
    assert info["bytecodes"] == 1 and info["bytecode_paths"] == [], info["bytecode_paths"]
    assert info["env_image"] == "vfiber-studio.hdr"
    image = next(im for im in info["images"] if im["name"] == info["env_image"])
    assert image["packed"] and image["filepath"] == "//vfiber-studio.hdr"     # Blender's relative name, no folder
    assert image["packed_paths"] == ["//vfiber-studio.hdr"]
    data = _blend_bytes(blend)
    assert b"vfiber-light-" not in data and str(tmp_path).encode() not in data    # where the map was written
    h, w = environment_image("studio").shape[:2]
    assert image["size"] == [w, h]
    env = rig["environment"]
    assert env["rotation_degrees"] == pytest.approx(55.0)       # environment_rotation + rig_rotation
    assert info["mapping"] == "TEXTURE"
    np.testing.assert_allclose(info["rotation"], [0.0, 0.0, np.radians(env["rotation_degrees"])], atol=1e-6)
    assert info["strength"] == pytest.approx(XB.SUN_PER_INTENSITY * env["strength"], rel=1e-6)


@blender_test
@pytest.mark.blender
def test_rim_light_changes_the_cycles_picture(tmp_path):
    """The rim lamp alone (key and ambient fill at 0), off then on, same seed and samples: off, the fibers
    are black; on, the rim lights them, so the exported rim is a lamp Cycles uses. Two things of the OSL
    shader (osl/stages/container.osl, not the export) shape this check: its "density" self-shadow weighs
    the closure by the key and fill only (both 0 here: the closure would be 0), so the check uses traced
    shadows; and its Kajiya-Kay diffuse lobe is diffuse(Nf), dark for a light straight behind the fiber,
    so the rim is turned 60 degrees off straight behind."""
    rgba = {}
    for rim in ("0", "2"):
        blend = tmp_path / f"rim{rim}.blend"
        _export("default", blend, f"light.rim_intensity={rim}", "light.rim_azimuth=60", "look.light_intensity=0",
                "look.ambient=0", "look.self_shadow=traced")
        _render_like_a_farm(blend, tmp_path / f"rim{rim}.npy", "--samples", "4")
        rgba[rim] = np.load(tmp_path / f"rim{rim}.npy")
    covered = (rgba["0"][..., 3] > 0.5) & (rgba["2"][..., 3] > 0.5)
    assert covered.sum() > 500
    off, on = rgba["0"][covered][:, :3], rgba["2"][covered][:, :3]
    lit = float((on.max(1) > 1e-3).mean())
    print(f"\nrim off: mean {off.mean():.4f}; rim on: mean {on.mean():.4f}, {lit:.0%} of {covered.sum()} fiber "
          f"pixels lit")
    assert off.max() == 0.0
    assert on.mean() > 0.005 and lit > 0.1


def test_portable_bytecode_keeps_the_code_and_drops_the_machine_paths():
    from app.export.blend import TEXT_NAME, portable_bytecode

    oso = ("OpenShadingLanguage 1.00\n# Compiled by oslc 1.14.7.0\n"
           "# options: -o /tmp/tmpyetq5dfv.oso -I/home/ann/.venv/bpy/scripts/addons_core/cycles/shader\n"
           "shader vfiber_carpet\n# /tmp/tmp46piw7yw.osl:1860\n"
           '\tadd\t$tmp1 a b\t%filename{"/tmp/tmp46piw7yw.osl"} %line{1860} %argrw{"wrr"}\n'
           '\tmul\t$tmp2 c d\t%filename{".venv/lib/bpy/shader/stdosl.h"} %line{12} %argrw{"wrr"}\n')
    got = portable_bytecode(oso)
    assert "/tmp" not in got and "/home" not in got and ".venv" not in got
    assert f'%filename{{"{TEXT_NAME}"}} %line{{1860}}' in got and '%filename{"stdosl.h"} %line{12}' in got
    assert f"# {TEXT_NAME}:1860" in got and "# Compiled by oslc 1.14.7.0" in got
    # every instruction line is the same but for its file hint
    code = [ln for ln in oso.split("\n") if not ln.startswith("#")]
    kept = [ln for ln in got.split("\n") if not ln.startswith("#")]
    assert [ln.split("%filename")[0] for ln in kept] == [ln.split("%filename")[0] for ln in code]
