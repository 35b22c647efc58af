"""Groom loading (.hair .data .tfx .ply), orientation, resampling and guide building.

The shared real grooms are read in place from ``../shared/hair-data`` (never copied into the project); tests
that need them are skipped when that folder is missing. Everything about malformed input is also exercised on
small synthetic files written here, so a regression in the untrusted-input handling fails even without data.
"""

from __future__ import annotations

import struct
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from app.scene.grooms import guides as groom_guides
from app.scene.grooms import load as groom_load
from app.scene.grooms import (
    Groom, GroomError, default_radius, load_groom, parse_groom, resample, resample_many, strands_to_guides,
    up_rotation,
)
from tests.support.paths import HAIR_DATA

DATA = HAIR_DATA
needs_data = pytest.mark.skipif(not DATA.is_dir(), reason=f"shared hair data not found at {DATA}")

# name -> (strands, vertices, up axis auto must pick, tips above roots after conversion?)
SHARED = {
    "harolongo.data": (7905, 166005, "y", False),
    "sintel_hair.tfx": (228, 7296, "y", False),
    "Ratboy_mohawk.tfx": (2228, 71296, "y", True),
    "Bangs_100.hair": (100, 1165, "x", False),      # README: gravity about -X, so the file's +X is up
    "Curly_100.ply": (100, 2528, "x", False),       # same CT2Hair frame as Bangs
}
SMALL = ["Bangs_100.hair", "Curly_100.ply", "sintel_hair.tfx"]

MEM_LIMIT = 200 * 1024**2


# --------------------------------------------------------------------------------------------------------
# Writers for synthetic files, one per format, following the README layouts.

def hair_bytes(strands: list[np.ndarray], thickness: list[np.ndarray] | None = None,
               colors: list[np.ndarray] | None = None) -> bytes:
    pts = np.concatenate(strands).astype("<f4")
    flags = 1 | 2 | (4 if thickness is not None else 0) | (16 if colors is not None else 0)
    head = b"HAIR" + struct.pack("<4I", len(strands), len(pts), flags, 0) + struct.pack("<5f", 1, 0, 1, 1, 1)
    head += b"synthetic".ljust(88, b"\0")
    body = np.array([len(s) - 1 for s in strands], "<u2").tobytes() + pts.tobytes()
    if thickness is not None:
        body += np.concatenate(thickness).astype("<f4").tobytes()
    if colors is not None:
        body += np.concatenate(colors).astype("<f4").tobytes()
    return head + body


def data_bytes(strands: list[np.ndarray]) -> bytes:
    out = struct.pack("<i", len(strands))
    for s in strands:
        out += struct.pack("<i", len(s)) + np.asarray(s, "<f4").tobytes()
    return out


def tfx_bytes(strands: list[np.ndarray], strand_thickness: np.ndarray | None = None) -> bytes:
    ns, nv = len(strands), len(strands[0])
    xyzw = np.ones((ns, nv, 4), "<f4")
    xyzw[:, :, :3] = np.stack(strands)
    xyzw[:, 0, 3] = 0.0
    o_thick = 160 + xyzw.nbytes if strand_thickness is not None else 0
    head = struct.pack("<f7I", 4.0, ns, nv, 160, 0, 0, o_thick, 0) + bytes(128)
    body = xyzw.tobytes()
    if strand_thickness is not None:
        body += np.asarray(strand_thickness, "<f4").tobytes()
    return head + body


def ply_bytes(strands: list[np.ndarray], fmt: str = "binary_little_endian", edges: bool = True,
              extra: str = "") -> bytes:
    pts = np.concatenate(strands)
    nseg = np.array([len(s) - 1 for s in strands])
    vert = np.zeros(len(pts), [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("red", "u1"), ("green", "u1"),
                               ("blue", "u1")])
    vert["x"], vert["y"], vert["z"] = pts.T
    vert["red"], vert["green"], vert["blue"] = 255, 128, 0
    starts = np.concatenate([[0], np.cumsum(nseg + 1)[:-1]])
    e1 = np.concatenate([np.arange(a, a + n) for a, n in zip(starts, nseg)]).astype("<i4")
    head = (f"ply\nformat {fmt} 1.0\ncomment synthetic\nelement vertex {len(pts)}\nproperty float x\n"
            "property float y\nproperty float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
            f"element strand {len(strands)}\nproperty ushort nsegs\n{extra}")
    if edges:
        head += f"element edge {len(e1)}\nproperty int vertex1\nproperty int vertex2\n"
    head += "end_header\n"
    body = vert.tobytes() + nseg.astype("<u2").tobytes()
    if edges:
        body += np.stack([e1, e1 + 1], axis=1).astype("<i4").tobytes()
    return head.encode() + body


def hanging(n_strands: int = 6, n_vertices: int = 5, length: float = 4.0, seed: int = 0) -> list[np.ndarray]:
    """Strands with roots on a 1-unit patch in the z=10 plane hanging straight down -Z (a Z-up groom)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n_strands):
        root = np.array([rng.uniform(0, 1), rng.uniform(0, 1), 10.0])
        t = np.linspace(0, 1, n_vertices)[:, None]
        out.append(root + t * np.array([0.1, 0.0, -length]))
    return out


WRITERS = {"hair": hair_bytes, "data": data_bytes, "tfx": tfx_bytes, "ply": ply_bytes}


def synthetic_files() -> dict[str, bytes]:
    s = hanging()
    return {f"synth.{fmt}": w(s) for fmt, w in WRITERS.items()}


def shared_or_synthetic() -> dict[str, bytes]:
    """Every shared file when the data is there, plus the synthetic ones in any case."""
    out = synthetic_files()
    if DATA.is_dir():
        out.update({name: (DATA / name).read_bytes() for name in SHARED})
    return out


def expect_groom_error_only(name: str, buf: bytes) -> Groom | None:
    """Parse and demand either a sound groom or a GroomError naming the file, never a parser gap."""
    try:
        g = parse_groom(buf, name=name, suffix=Path(name).suffix)
    except GroomError as exc:
        msg = str(exc)
        assert msg.startswith(f"{name}: "), msg
        assert "unexpected parser failure" not in msg, msg
        return None
    _assert_sound(g)
    return g


def _assert_sound(g: Groom) -> None:
    points, offsets = g.packed()
    assert g.n_strands > 0 and points.shape[1] == 3
    assert np.all(np.diff(offsets) >= 2) and np.isfinite(points).all()


# --------------------------------------------------------------------------------------------------------
# The shared real grooms

@needs_data
@pytest.mark.parametrize("name", list(SHARED))
def test_shared_file_counts_and_orientation(name: str) -> None:
    n_strands, n_vertices, up, tips_up = SHARED[name]
    g = load_groom(DATA / name)
    assert (g.n_strands, g.n_vertices) == (n_strands, n_vertices)
    assert g.skipped == {}, "the shared files hold no unusable strands"
    assert g.up == up, g.up_reason
    assert g.format == name.rsplit(".", 1)[1]
    assert all(s.dtype == np.float64 and s.shape[1] == 3 for s in g.strands)
    roots = np.array([s[0] for s in g.strands])
    tips = np.array([s[-1] for s in g.strands])
    rise = float((tips - roots)[:, 2].mean())
    # Z-up after conversion: long hair hangs below its roots; the mohawk's spikes rise.
    assert (rise > 0) == tips_up, (name, rise)


@needs_data
def test_harolongo_bbox_is_a_28_unit_head_standing_on_z() -> None:
    g = load_groom(DATA / "harolongo.data")
    lo, hi = g.bbox()
    ext = hi - lo
    assert 27.0 < ext[2] < 29.5 and np.argmax(ext) == 2
    # Y-up to Z-up is (x, y, z) -> (x, -z, y): the file's Y range becomes the Z range.
    raw = load_groom(DATA / "harolongo.data", up="z")
    rlo, rhi = raw.bbox()
    np.testing.assert_allclose([lo[2], hi[2]], [rlo[1], rhi[1]])
    np.testing.assert_allclose([lo[1], hi[1]], [-rhi[2], -rlo[2]])


@needs_data
def test_ratboy_is_metre_scale_and_scale_multiplies() -> None:
    g = load_groom(DATA / "Ratboy_mohawk.tfx")
    lo, hi = g.bbox()
    assert np.all(hi - lo < 1.2) and hi[2] - lo[2] > 0.8      # under 1.2 m, about 0.9 m tall
    g100 = load_groom(DATA / "Ratboy_mohawk.tfx", scale=100.0)
    lo2, hi2 = g100.bbox()
    np.testing.assert_allclose(lo2, 100 * lo)
    np.testing.assert_allclose(hi2, 100 * hi)
    assert g.meta["pinned_vertices"] == 2 * 2228           # TressFX pins two root vertices per strand here
    lengths = g.lengths()
    assert int((lengths < 1e-3).sum()) == 9                # the README's 9 near-empty strands


@needs_data
def test_explicit_up_overrides_auto() -> None:
    g = load_groom(DATA / "Bangs_100.hair", up="z")
    assert g.up == "z" and g.up_reason == "given"
    lo, hi = g.bbox()
    np.testing.assert_allclose(lo, [11.855, 17.103, 31.752], atol=1e-3)   # untouched file coordinates
    np.testing.assert_allclose(hi, [247.856, 236.948, 204.862], atol=1e-3)


@needs_data
def test_curly_ply_colours_are_per_vertex_in_unit_range() -> None:
    g = load_groom(DATA / "Curly_100.ply")
    assert g.colors is not None and len(g.colors) == g.n_strands
    assert all(c.shape == s.shape for c, s in zip(g.colors, g.strands))
    allc = np.concatenate(g.colors)
    assert allc.min() >= 0 and allc.max() <= 1 and allc.max() > 0.5


@needs_data
def test_harolongo_loads_well_under_a_second() -> None:
    best = min(_timed(lambda: load_groom(DATA / "harolongo.data")) for _ in range(3))
    assert best < 0.5, f"harolongo took {best:.3f} s"


def _timed(fn) -> float:
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


@needs_data
@pytest.mark.parametrize("name", list(SHARED))
def test_guides_from_every_shared_file(name: str) -> None:
    g = load_groom(DATA / name)
    lo, hi = g.bbox()
    diag = float(np.linalg.norm(hi - lo))
    expected_dropped = 9 if name == "Ratboy_mohawk.tfx" else 0

    pl, radii = guides = strands_to_guides(g, segments=8, cluster=0)
    assert guides.dropped == ({"shorter than min_length": 9} if expected_dropped else {})
    assert len(pl) == g.n_strands - expected_dropped == len(radii)
    assert all(p.shape == (9, 3) for p in pl)
    assert np.all(radii == radii[0]) and 0 < radii[0] < 0.05 * diag
    kept = np.flatnonzero(guides.labels >= 0)
    np.testing.assert_allclose(np.array([p[0] for p in pl]), np.array([g.strands[i][0] for i in kept]))

    pl50, r50 = g50 = strands_to_guides(g, segments=8, cluster=50, seed=3)
    assert len(pl50) == 50 == len(r50)
    assert np.all(np.isfinite(r50)) and np.all(r50 >= radii[0] - 1e-12)
    assert np.all(r50 < diag)
    assert set(np.unique(g50.labels[g50.labels >= 0])) == set(range(50))
    # Each guide starts near its members' roots: within its container radius of their mean root.
    roots = np.array([s[0] for s in g.strands])
    for k in range(50):
        members = roots[g50.labels == k]
        assert np.linalg.norm(members.mean(axis=0) - pl50[k][0]) < 1e-6 * diag + 1e-9
    # Same seed, same guides.
    pl50b, r50b = strands_to_guides(g, segments=8, cluster=50, seed=3)
    np.testing.assert_array_equal(np.stack(pl50), np.stack(pl50b))


@needs_data
def test_cluster_radius_covers_most_members() -> None:
    g = load_groom(DATA / "sintel_hair.tfx")
    res = resample_many(g.strands, 8)
    guides = strands_to_guides(g, cluster=20, seed=1)
    covered = []
    for i, k in enumerate(guides.labels):
        d = groom_guides._point_polyline_distance(res[i:i + 1], guides.polylines[k][None]).max()
        covered.append(d <= guides.radii[k] + 1e-9)
    assert np.mean(covered) >= 0.85


# --------------------------------------------------------------------------------------------------------
# Format round trips and documented skips on synthetic files

@pytest.mark.parametrize("fmt", list(WRITERS))
def test_round_trip_each_format(fmt: str, tmp_path: Path) -> None:
    strands = hanging(5, 4)
    path = tmp_path / f"g.{fmt}"
    path.write_bytes(WRITERS[fmt](strands))
    g = load_groom(path, up="z")
    assert g.n_strands == 5 and g.n_vertices == 20 and g.format == fmt
    np.testing.assert_allclose(np.concatenate(g.strands), np.concatenate(strands), rtol=1e-6)
    # Auto: hanging down -Z is Z-up for formats without a convention; TressFX/HairSalon strands that are this
    # long and clearly hanging override their Y-up convention.
    assert load_groom(path).up == "z"


def test_hair_thickness_and_colours_follow_kept_strands() -> None:
    strands = hanging(3, 4)
    strands[1] = np.array([[0, 0, 0.0]])                      # one vertex: dropped with its attributes
    thick = [np.full(len(s), i + 1.0) for i, s in enumerate(strands)]
    cols = [np.full((len(s), 3), 0.1 * (i + 1)) for i, s in enumerate(strands)]
    g = parse_groom(hair_bytes(strands, thick, cols), name="t.hair", suffix=".hair", up="z", scale=2.0)
    assert g.skipped == {"one vertex": 1}
    assert [t[0] for t in g.thickness] == [2.0, 6.0]         # thickness scales with the coordinates
    np.testing.assert_allclose([c[0, 0] for c in g.colors], [0.1, 0.3], rtol=1e-6)


def test_tfx_strand_thickness_broadcasts_to_vertices() -> None:
    g = parse_groom(tfx_bytes(hanging(3, 4), np.array([1.0, 2.0, 3.0])), name="t.tfx", suffix=".tfx", up="z")
    assert [list(t) for t in g.thickness] == [[1.0] * 4, [2.0] * 4, [3.0] * 4]


def test_unusable_strands_are_skipped_and_counted() -> None:
    good = hanging(4, 5)
    bad_nan = good[0].copy()
    bad_nan[2, 1] = np.nan
    bad_inf = good[1].copy()
    bad_inf[0, 0] = np.inf
    strands = good + [np.zeros((0, 3)), np.ones((1, 3)), np.ones((4, 3)), bad_nan, bad_inf]
    g = parse_groom(data_bytes(strands), name="s.data", suffix=".data", up="z")
    assert g.n_strands == 4
    assert g.skipped == {"no vertices": 1, "one vertex": 1, "non-finite": 2, "zero length": 1}
    np.testing.assert_allclose(np.concatenate(g.strands), np.concatenate(good), rtol=1e-6)


def test_nothing_usable_is_an_error() -> None:
    with pytest.raises(GroomError, match=r"^z\.data: none of the 2 strands is usable"):
        parse_groom(data_bytes([np.ones((1, 3)), np.ones((3, 3))]), name="z.data", suffix=".data")


def test_error_message_names_file_and_problem(tmp_path: Path) -> None:
    buf = hair_bytes(hanging(100, 12)[:100])
    path = tmp_path / "Bangs.hair"
    path.write_bytes(buf[:128 + 200 + 3000])
    with pytest.raises(GroomError, match=r"^Bangs\.hair: header says 100 strands with 1200 points, which needs "
                                         r"14600 bytes of strand data, but the file holds only 3200"):
        load_groom(path)


def test_format_rejections(tmp_path: Path) -> None:
    s = hanging(3, 4)
    cases = {
        "ascii.ply": (ply_bytes(s, fmt="ascii"), "not supported"),
        "big.ply": (ply_bytes(s, fmt="binary_big_endian"), "not supported"),
        "list.ply": (ply_bytes(s, extra="element face 0\nproperty list uchar int vertex_indices\n"), "list"),
        "nostrand.ply": (ply_bytes(s).replace(b"element strand 3\nproperty ushort nsegs\n", b""), None),
        "text.tfx": (b"version 2.0\n" + bytes(400), "version field"),
        "nopoints.hair": (b"HAIR" + struct.pack("<4I", 1, 2, 1, 0) + bytes(108) + bytes(40), "no points array"),
        "weird.xyz": (b"\0" * 64, "unknown groom format"),
    }
    for name, (buf, what) in cases.items():
        (tmp_path / name).write_bytes(buf)
        with pytest.raises(GroomError) as err:
            load_groom(tmp_path / name)
        assert str(err.value).startswith(name + ":")
        if what:
            assert what in str(err.value), str(err.value)


def test_ply_header_is_parsed_not_assumed() -> None:
    # Extra comments (one mentioning end_header), CRLF line ends and a reordered property list still load;
    # an unknown element is skipped over by its declared size.
    strands = hanging(3, 4)
    buf = ply_bytes(strands, extra="comment the end_header line ends this\nelement note 2\nproperty double w\n")
    head, body = buf.split(b"\nend_header\n", 1)
    head += b"\n"
    # The 'note' records go after the strand records: 12 vertices of 15 bytes, then 3 nsegs of 2 bytes.
    at = 12 * 15 + 3 * 2
    body = body[:at] + np.zeros(2, "<f8").tobytes() + body[at:]
    crlf = head.replace(b"\n", b"\r\n") + b"end_header\r\n"
    for variant in (head + b"end_header\n" + body, crlf + body):
        g = parse_groom(variant, name="h.ply", suffix=".ply", up="z")
        np.testing.assert_allclose(np.concatenate(g.strands), np.concatenate(strands), rtol=1e-6)
        assert any("note" in w for w in g.warnings)


def test_ply_edges_must_be_consecutive_pairs() -> None:
    buf = bytearray(ply_bytes(hanging(2, 3)))
    # The last edge's vertex2 (final 4 bytes) now points back at the root.
    buf[-4:] = struct.pack("<i", 0)
    with pytest.raises(GroomError, match="consecutive vertex pairs"):
        parse_groom(bytes(buf), name="e.ply", suffix=".ply")


def test_magic_wins_over_extension_and_missing_file() -> None:
    g = parse_groom(hair_bytes(hanging()), name="odd.data", suffix=".data", up="z")
    assert g.format == "hair" and g.warnings
    with pytest.raises(GroomError, match="^nope.hair: cannot read"):
        load_groom(Path("/nonexistent/dir/nope.hair"))


def test_size_guard(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    path = tmp_path / "big.data"
    path.write_bytes(data_bytes(hanging()))
    monkeypatch.setattr(groom_load, "MAX_FILE_BYTES", 100)
    with pytest.raises(GroomError, match="larger than the 100-byte limit"):
        load_groom(path)


def test_bad_options_are_value_errors() -> None:
    buf = data_bytes(hanging())
    with pytest.raises(ValueError, match="up must be one of"):
        parse_groom(buf, "data", up="sideways")
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="scale"):
            parse_groom(buf, "data", scale=bad)


# --------------------------------------------------------------------------------------------------------
# Orientation

@pytest.mark.parametrize("up", ["x", "-x", "y", "-y", "z", "-z"])
def test_up_rotation_is_proper_and_lifts_the_named_axis(up: str) -> None:
    r = up_rotation(up)
    axis = np.zeros(3)
    axis["xyz".index(up[-1])] = -1.0 if up.startswith("-") else 1.0
    np.testing.assert_allclose(r @ axis, [0, 0, 1])
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
    assert np.isclose(np.linalg.det(r), 1.0)


@pytest.mark.parametrize("up", ["x", "-x", "y", "-y", "z"])
def test_auto_recovers_a_rotated_hanging_groom(up: str) -> None:
    # Write a Z-up groom as if its file had ``up`` pointing up, then check auto finds it and undoes it.
    z_up = hanging(8, 6)
    to_file = up_rotation(up).T
    strands = [s @ to_file.T for s in z_up]
    g = parse_groom(ply_bytes(strands), name="r.ply", suffix=".ply")
    assert g.up == up, g.up_reason
    np.testing.assert_allclose(np.concatenate(g.strands), np.concatenate(z_up), atol=1e-5)


def test_short_tfx_fur_keeps_the_y_up_convention() -> None:
    # Short spikes swept along -Z (like Ratboy's mohawk) are not evidence of gravity.
    rng = np.random.default_rng(0)
    strands = []
    for y in np.linspace(0, 10, 40):
        root = np.array([rng.uniform(-0.1, 0.1), y, rng.uniform(-1, 1)])
        strands.append(root + np.linspace(0, 1, 4)[:, None] * np.array([0, 0.05, -0.5]))
    g = parse_groom(tfx_bytes(strands), name="fur.tfx", suffix=".tfx")
    assert g.up == "y", g.up_reason
    g_ply = parse_groom(ply_bytes(strands), name="fur.ply", suffix=".ply")
    assert g_ply.up == "z", g_ply.up_reason          # no convention: the clear -Z sweep decides


# --------------------------------------------------------------------------------------------------------
# Resampling and guides on synthetic strands

def test_resample_keeps_endpoints_and_length() -> None:
    t = np.linspace(0, 4 * np.pi, 300)
    helix = np.stack([np.cos(t), np.sin(t), 0.3 * t], axis=1)
    length = np.linalg.norm(np.diff(helix, axis=0), axis=1).sum()
    for n in (1, 8, 64, 500):
        r = resample(helix, n)
        assert r.shape == (n + 1, 3)
        np.testing.assert_array_equal(r[0], helix[0])
        np.testing.assert_array_equal(r[-1], helix[-1])
        rl = np.linalg.norm(np.diff(r, axis=0), axis=1).sum()
        assert rl <= length + 1e-9
    assert rl > 0.999 * length
    line = np.array([[0, 0, 0], [1, 0, 0], [1, 0, 0], [4, 0, 0.0]])      # with a duplicate vertex
    np.testing.assert_allclose(resample(line, 4)[:, 0], [0, 1, 2, 3, 4])
    with pytest.raises(ValueError):
        resample(np.ones((3, 3)), 4)


def test_resample_many_matches_one_by_one() -> None:
    strands = hanging(5, 7) + [np.array([[0, 0, 0], [0, 0, 1e-7], [0, 1e-7, 1e-7]])]
    many = resample_many(strands, 6)
    for s, m in zip(strands, many):
        np.testing.assert_allclose(m, resample(s, 6), atol=1e-12)


def test_default_radius_from_root_spacing() -> None:
    xs, ys = np.meshgrid(np.arange(40) * 0.2, np.arange(30) * 0.2)
    roots = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], axis=1)
    roots = np.concatenate([roots, roots[:5]])                        # duplicate roots do not count
    assert default_radius(roots) == pytest.approx(0.75 * 0.2)
    assert default_radius(roots, max_queries=50) == pytest.approx(0.75 * 0.2)
    assert default_radius(roots[:1]) == 1.0


def test_guides_clusters_and_drops() -> None:
    # Two separate locks of hair plus one stub; two clusters must find the locks.
    a = [s + np.array([0, 0, 0]) for s in hanging(10, 6, seed=1)]
    b = [s + np.array([20, 0, 0]) for s in hanging(10, 6, seed=2)]
    stub = [np.array([[5, 5, 10], [5, 5, 10 - 1e-5]])]
    g = parse_groom(ply_bytes(a + b + stub), name="l.ply", suffix=".ply", up="z")
    pl, radii = guides = strands_to_guides(g, segments=4, cluster=2, seed=0)
    assert guides.dropped == {"shorter than min_length": 1}
    assert guides.labels[-1] == -1
    assert len(set(guides.labels[:10])) == 1 and len(set(guides.labels[10:20])) == 1
    assert guides.labels[0] != guides.labels[10]
    for k in range(2):
        members = resample_many([g.strands[i] for i in np.flatnonzero(guides.labels == k)], 4)
        np.testing.assert_allclose(pl[k], members.mean(axis=0), atol=1e-9)
        assert 0.3 < radii[k] < 1.5                                  # the lock is 1 unit wide
    # More clusters than strands: one guide per strand, all with the given radius floor.
    pl, radii = strands_to_guides(g, cluster=1000, radius=0.25)
    assert len(pl) == 20 and np.all(radii == 0.25)
    with pytest.raises(GroomError, match="no strand is at least"):
        strands_to_guides(g, min_length=1e9)


# --------------------------------------------------------------------------------------------------------
# Untrusted input: truncation, corruption, absurd counts

def _peak_bytes(fn) -> int:
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


@pytest.mark.filterwarnings("error::RuntimeWarning")
def test_truncated_copies_raise_groom_error(tmp_path: Path) -> None:
    for name, buf in shared_or_synthetic().items():
        n = len(buf)
        cuts = sorted({0, 1, 3, 4, 5, 127, 128, 129, 159, 160, 161, n // 2, n - 1, n - 4, n - 12}
                      | set(np.linspace(0, n - 1, 25 if n > 200_000 else 60).astype(int).tolist()))
        for cut in cuts:
            if cut >= n:
                continue
            path = tmp_path / name
            path.write_bytes(buf[:cut])
            peak = _peak_bytes(lambda: _load_expect_error(path))
            assert peak < MEM_LIMIT, (name, cut, peak)


def _load_expect_error(path: Path) -> None:
    try:
        load_groom(path)
    except GroomError as exc:
        assert str(exc).startswith(path.name + ":") and "unexpected parser failure" not in str(exc), str(exc)
        return
    # A cut can only land on a valid file where the format has no total length (trailing data ignored):
    # e.g. a .tfx without its optional arrays still has all positions. Anything loaded must be sound.
    _assert_sound(load_groom(path))


@pytest.mark.filterwarnings("error::RuntimeWarning")
def test_byte_flipped_copies(tmp_path: Path) -> None:
    rng = np.random.default_rng(1234)
    for name, buf in shared_or_synthetic().items():
        small = len(buf) < 200_000
        header = min(len(buf), 200 if small else 48)
        # Every header byte (where all counts live) plus random positions anywhere. Memory is traced on the
        # small files, where any allocation driven by a corrupt count would stand out; the two large ones get
        # fewer flips untraced (tracing a 166k-vertex load costs most of a second).
        positions = list(range(header)) + rng.integers(0, len(buf), 40 if small else 12).tolist()
        for i, pos in enumerate(positions):
            flipped = bytearray(buf)
            flipped[pos] ^= 0xFF if i % 2 else 1 << int(rng.integers(8))
            if small:
                peak = _peak_bytes(lambda: expect_groom_error_only(name, bytes(flipped)))
                assert peak < MEM_LIMIT, (name, pos, peak)
            else:
                expect_groom_error_only(name, bytes(flipped))
        # A few through the file system too, as a user would hit them.
        for pos in rng.integers(0, header, 3):
            flipped = bytearray(buf)
            flipped[pos] ^= 0xFF
            (tmp_path / name).write_bytes(bytes(flipped))
            _load_expect_error(tmp_path / name)


ABSURD_U32 = [2**31, 2**32 - 1, 2**31 - 1]         # 2**32 - 1 is -1 to a signed reader


def _absurd_variants(name: str, buf: bytes) -> list[bytes]:
    """Copies with each count field set to absurd values, per format."""
    fmt = name.rsplit(".", 1)[1]
    out = []
    if fmt == "ply":
        for elem in (b"vertex", b"strand", b"edge"):
            head_end = buf.index(b"end_header")
            line_at = buf.index(b"element " + elem + b" ")
            line_end = buf.index(b"\n", line_at)
            for v in (b"2147483648", b"4294967295", b"-1", b"0", b"99999999999999999999"):
                out.append(buf[:line_at] + b"element " + elem + b" " + v + buf[line_end:])
            assert line_at < head_end
        return out
    fields = {"hair": [4, 8, 16], "data": [0, 4], "tfx": [4, 8, 12, 16, 20, 24, 28]}[fmt]
    for off in fields:
        for v in ABSURD_U32 + [0, 1]:
            b = bytearray(buf)
            b[off:off + 4] = struct.pack("<I", v)
            out.append(bytes(b))
    return out


@pytest.mark.filterwarnings("error::RuntimeWarning")
def test_absurd_header_counts_stay_small(tmp_path: Path) -> None:
    files = synthetic_files()
    if DATA.is_dir():
        files.update({n: (DATA / n).read_bytes() for n in SMALL})
    for name, buf in files.items():
        for k, variant in enumerate(_absurd_variants(name, buf)):
            path = tmp_path / name
            path.write_bytes(variant)
            peak = _peak_bytes(lambda: _load_expect_error(path))
            assert peak < MEM_LIMIT, (name, k, peak)


@pytest.mark.filterwarnings("error::RuntimeWarning")
def test_absurd_counts_on_tiny_files_are_rejected() -> None:
    # A 2**31 count in a file of a few bytes must be refused from the size check alone.
    tiny = {
        "a.data": struct.pack("<i", 2**31 - 1) + bytes(16),
        "b.data": struct.pack("<i", -1) + bytes(16),
        "c.data": struct.pack("<ii", 1, 2**31 - 1) + bytes(24),
        "d.data": struct.pack("<ii", 1, -5) + bytes(24),
        "e.hair": b"HAIR" + struct.pack("<4I", 2**31, 2**31, 3, 0) + bytes(120),
        "f.hair": b"HAIR" + struct.pack("<4I", 2**31, 2**32 - 1, 2, 2**32 - 1) + bytes(120),
        "g.tfx": struct.pack("<f7I", 4.0, 2**31, 32, 160, 0, 0, 0, 0) + bytes(200),
        "h.tfx": struct.pack("<f7I", 4.0, 1, 2**32 - 1, 160, 0, 0, 0, 0) + bytes(200),
        "i.tfx": struct.pack("<f7I", 4.0, 1, 2, 2**32 - 64, 0, 0, 0, 0) + bytes(200),
        "j.ply": b"ply\nformat binary_little_endian 1.0\nelement vertex 2147483648\nproperty float x\n"
                 b"property float y\nproperty float z\nelement strand 1\nproperty ushort nsegs\nend_header\n"
                 + bytes(64),
    }
    for name, buf in tiny.items():
        peak = _peak_bytes(lambda: pytest.raises(GroomError, parse_groom, buf, name=name,
                                                 suffix=Path(name).suffix))
        assert peak < 10 * 1024**2, (name, peak)


@pytest.mark.filterwarnings("error::RuntimeWarning")
@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_random_mutations_never_escape(data: st.DataObject) -> None:
    files = synthetic_files()
    if DATA.is_dir():
        files.update({n: (DATA / n).read_bytes() for n in SMALL})
    name = data.draw(st.sampled_from(sorted(files)))
    buf = bytearray(files[name])
    for _ in range(data.draw(st.integers(1, 4))):
        kind = data.draw(st.sampled_from(["word", "byte", "cut", "insert"]))
        if not buf:
            break
        # Bias positions to the first 200 bytes, where headers and counts are.
        pos = data.draw(st.one_of(st.integers(0, min(len(buf), 200) - 1), st.integers(0, len(buf) - 1)))
        if kind == "word":
            buf[pos:pos + 4] = struct.pack("<I", data.draw(st.sampled_from(
                ABSURD_U32 + [0, 1, 2, 3, 0x7FC00000, 0x7F800000])))
        elif kind == "byte":
            buf[pos] = data.draw(st.integers(0, 255))
        elif kind == "cut":
            del buf[pos:]
        else:
            buf[pos:pos] = data.draw(st.binary(min_size=1, max_size=8))
    expect_groom_error_only(name, bytes(buf))
