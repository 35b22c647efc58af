"""Readers of the four groom formats: Cem Yuksel ``.hair``, USC-HairSalon ``.data``, AMD TressFX 4 ``.tfx``
and strand ``.ply`` (binary little-endian, ``vertex``/``strand``/``edge`` elements).

Each reader turns the bytes of one file into a :class:`_Raw` (points and per-strand vertex counts, before
anything is skipped, rotated or split). Every file is untrusted input: each count in a header is checked
against the number of bytes the file really holds *before* anything is allocated from it, and anything wrong
is a :class:`~.groom.GroomError` that names the file.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass, field

import numpy as np

from .groom import GroomError

FORMATS = ("hair", "data", "tfx", "ply")
_EXTENSIONS = {".hair": "hair", ".data": "data", ".tfx": "tfx", ".ply": "ply"}
GROOM_SUFFIXES = tuple(_EXTENSIONS)  # the one list of groom file suffixes (CLI, viewer, presets, export)


@dataclass
class _Raw:
    """Raw parse result shared by the four formats, before skipping, rotation and splitting."""


    points: np.ndarray                 # (N, 3) float32/float64, strand after strand
    counts: np.ndarray                 # (S,) int64 vertex count per strand; may hold 0 or 1
    thickness: np.ndarray | None = None   # (N,)
    colors: np.ndarray | None = None      # (N, 3) in [0, 1] for 8-bit sources
    meta: dict[str, object] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)


def _plural(n: int, word: str) -> str:
    return f"{n} {word}" + ("" if n == 1 else "s")


def _parse_hair(buf: bytes, name: str) -> _Raw:
    size = len(buf)
    if size < 128:
        raise GroomError(f"{name}: {size} bytes is shorter than the 128-byte .hair header")
    if buf[:4] != b"HAIR":
        raise GroomError(f"{name}: does not start with 'HAIR', so it is not a Cem Yuksel .hair file")
    ns, npts, flags, dseg = struct.unpack_from("<4I", buf, 4)
    dthick, dtrans, r, g, b = struct.unpack_from("<5f", buf, 20)
    info = buf[40:128].split(b"\0", 1)[0].decode("latin-1")
    warnings = []
    if flags & ~0x1F:
        warnings.append(f"unknown flag bits {flags & ~0x1F:#x} ignored")
    if not flags & 2:
        raise GroomError(f"{name}: flags {flags:#x} say there is no points array, so there is no geometry")
    if ns == 0:
        raise GroomError(f"{name}: header says 0 strands")
    has_seg, has_thick, has_trans, has_col = bool(flags & 1), bool(flags & 4), bool(flags & 8), bool(flags & 16)
    floats_per_point = 3 + has_thick + has_trans + 3 * has_col
    # Python ints: a 2**32-1 count cannot overflow here, and nothing is allocated until it fits the file.
    need = 2 * ns * has_seg + 4 * floats_per_point * npts
    have = size - 128
    if need > have:
        raise GroomError(f"{name}: header says {_plural(ns, 'strand')} with {_plural(npts, 'point')}, which "
                         f"needs {need} bytes of strand data, but the file holds only {have}")
    off = 128
    if has_seg:
        counts = np.frombuffer(buf, "<u2", ns, off).astype(np.int64) + 1
        off += 2 * ns
        total = int(counts.sum())
        if total != npts:
            raise GroomError(f"{name}: the segments array adds up to {total} points but the header says {npts}")
    else:
        if ns * (dseg + 1) != npts:
            raise GroomError(f"{name}: no segments array, so {ns} strands of {dseg} default segments should "
                             f"hold {ns * (dseg + 1)} points, but the header says {npts}")
        counts = np.full(ns, dseg + 1, np.int64)
    points = np.frombuffer(buf, "<f4", 3 * npts, off).reshape(npts, 3)
    off += 12 * npts
    thickness = None
    if has_thick:
        thickness = np.frombuffer(buf, "<f4", npts, off)
        off += 4 * npts
    if has_trans:
        off += 4 * npts            # transparency does not drive anything in vfiber
    colors = None
    if has_col:
        colors = np.frombuffer(buf, "<f4", 3 * npts, off).reshape(npts, 3)
        off += 12 * npts
    if off < size:
        warnings.append(f"{size - off} trailing bytes ignored")
    meta: dict[str, object] = {"flags": flags, "default_segments": dseg, "default_thickness": dthick,
                               "default_transparency": dtrans, "default_color": (r, g, b), "info": info}
    return _Raw(points, counts, thickness, colors, meta, warnings)


def _parse_data(buf: bytes, name: str) -> _Raw:
    size = len(buf)
    if size < 4:
        raise GroomError(f"{name}: {size} bytes is too short for the .data strand count")
    (ns,) = struct.unpack_from("<i", buf, 0)
    if ns <= 0:
        raise GroomError(f"{name}: strand count {ns} is not positive")
    nwords = size // 4
    # Every strand record is at least its 4-byte vertex count, which bounds the loop below by the file size.
    if 1 + ns > nwords:
        raise GroomError(f"{name}: header says {_plural(ns, 'strand')} but the file's {size} bytes hold at most "
                         f"{nwords - 1} strand records")
    counts = np.empty(ns, np.int64)
    starts = np.empty(ns, np.int64)          # word index of each strand's first coordinate
    first = struct.unpack_from("<i", buf, 4)[0]
    ints = np.frombuffer(buf, "<i4", nwords)
    stride = 1 + 3 * first
    # Fast path: most .data files give every strand the same vertex count, which a strided view verifies at once.
    if first >= 0 and 1 + ns * stride == nwords and bool(np.all(ints[1::stride] == first)):
        counts[:] = first
        starts[:] = 2 + stride * np.arange(ns, dtype=np.int64)
    else:
        # Each record's position depends on every count before it, so this walk is sequential; it touches
        # one word per strand and stops at the first count that overruns the file.
        w = 1
        unpack = struct.Struct("<i").unpack_from
        for i in range(ns):
            if w >= nwords:
                raise GroomError(f"{name}: the file ends before strand {i} of {ns} (no vertex count left)")
            (n,) = unpack(buf, 4 * w)
            if n < 0:
                raise GroomError(f"{name}: strand {i} has a negative vertex count {n}")
            if w + 1 + 3 * n > nwords:
                raise GroomError(f"{name}: strand {i} says {_plural(n, 'vertex')} ({12 * n} bytes) but only "
                                 f"{4 * (nwords - w - 1)} bytes remain")
            counts[i] = n
            starts[i] = w + 1
            w += 1 + 3 * n
    total = int(counts.sum())
    used_words = 1 + ns + 3 * total
    warnings = []
    if 4 * used_words < size:
        warnings.append(f"{size - 4 * used_words} trailing bytes ignored")
    words = np.frombuffer(buf, "<f4", nwords)
    # Gather every strand's coordinate words in one indexing step (no per-strand copies).
    n3 = 3 * counts
    first3 = np.zeros(ns, np.int64)
    np.cumsum(n3[:-1], out=first3[1:])
    idx = np.repeat(starts - first3, n3) + np.arange(3 * total, dtype=np.int64)
    points = words[idx].reshape(total, 3)
    return _Raw(points, counts, meta={"strands_in_file": ns}, warnings=warnings)


def _parse_tfx(buf: bytes, name: str) -> _Raw:
    size = len(buf)
    if size < 160:
        raise GroomError(f"{name}: {size} bytes is shorter than the 160-byte TressFX header")
    (version,) = struct.unpack_from("<f", buf, 0)
    ns, nv, o_pos, o_suv, o_vuv, o_thick, o_col = struct.unpack_from("<7I", buf, 4)
    if not (math.isfinite(version) and 1.0 <= version < 100.0):
        raise GroomError(f"{name}: version field {version!r} is not a TressFX version; only binary TressFX 4 "
                         f".tfx files are read")
    if ns == 0:
        raise GroomError(f"{name}: header says 0 strands")
    if nv < 2:
        raise GroomError(f"{name}: header says {_plural(nv, 'vertex')} per strand; a strand needs at least 2")
    if o_pos == 0:
        raise GroomError(f"{name}: the vertex position offset is 0, so the file has no positions")
    nvert = ns * nv
    arrays = {"vertex positions": (o_pos, 16 * nvert), "strand UVs": (o_suv, 8 * ns),
              "vertex UVs": (o_vuv, 8 * nvert), "strand thickness": (o_thick, 4 * ns),
              "vertex colours": (o_col, 16 * nvert)}
    for what, (off, nbytes) in arrays.items():
        if off == 0:
            continue
        if off < 160:
            raise GroomError(f"{name}: {what} offset {off} points inside the 160-byte header")
        if off + nbytes > size:
            raise GroomError(f"{name}: header says {_plural(ns, 'strand')} of {nv} vertices, so the {what} at "
                             f"byte {off} need {nbytes} bytes, but the file is only {size} bytes long")
    xyzw = np.frombuffer(buf, "<f4", 4 * nvert, o_pos).reshape(nvert, 4)
    thickness = None
    if o_thick:
        thickness = np.repeat(np.frombuffer(buf, "<f4", ns, o_thick), nv)
    colors = None
    if o_col:
        colors = np.frombuffer(buf, "<f4", 4 * nvert, o_col).reshape(nvert, 4)[:, :3]
    # w = 0 marks vertices the simulation pins to the scalp; kept as a count for diagnostics only.
    meta = {"version": float(version), "vertices_per_strand": nv, "pinned_vertices": int((xyzw[:, 3] == 0).sum())}
    return _Raw(xyzw[:, :3], np.full(ns, nv, np.int64), thickness, colors, meta)


_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "<i2", "int16": "<i2",
    "ushort": "<u2", "uint16": "<u2", "int": "<i4", "int32": "<i4", "uint": "<u4", "uint32": "<u4",
    "float": "<f4", "float32": "<f4", "double": "<f8", "float64": "<f8",
}
_PLY_HEADER_MAX = 65536


def _parse_ply_header(buf: bytes, name: str) -> tuple[list[tuple[str, int, np.dtype]], int]:
    """Elements in file order as (name, count, packed little-endian record dtype) and the data offset."""
    if not buf.startswith(b"ply"):
        raise GroomError(f"{name}: does not start with 'ply', so it is not a PLY file")
    # Anchored at a line start, so a comment that mentions end_header cannot end the header early.
    end = buf.find(b"\nend_header", 0, _PLY_HEADER_MAX)
    end = end + 1 if end >= 0 else -1
    if end < 0:
        raise GroomError(f"{name}: no 'end_header' in the first {_PLY_HEADER_MAX} bytes")
    nl = buf.find(b"\n", end, end + 16)
    if nl < 0 or buf[end + 10:nl].strip(b"\r \t"):
        raise GroomError(f"{name}: 'end_header' is not followed by a line break")
    try:
        text = buf[:end].decode("ascii")
    except UnicodeDecodeError:
        raise GroomError(f"{name}: the PLY header is not ASCII text") from None
    lines = [ln.strip() for ln in text.replace("\r", "\n").split("\n")]
    if lines[0] != "ply":
        raise GroomError(f"{name}: the first line is {lines[0]!r}, not 'ply'")
    elements: list[tuple[str, int, list[tuple[str, str]]]] = []
    fmt = None
    for ln in lines[1:]:
        if not ln or ln.startswith(("comment", "obj_info")):
            continue
        tok = ln.split()
        if tok[0] == "format":
            fmt = tok[1:]
        elif tok[0] == "element":
            if len(tok) != 3 or not tok[2].isdigit():
                raise GroomError(f"{name}: malformed PLY line {ln!r}")
            if any(e[0] == tok[1] for e in elements):
                raise GroomError(f"{name}: element {tok[1]!r} is declared twice")
            elements.append((tok[1], int(tok[2]), []))
        elif tok[0] == "property":
            if not elements:
                raise GroomError(f"{name}: property {ln!r} comes before any element")
            if len(tok) >= 2 and tok[1] == "list":
                raise GroomError(f"{name}: element {elements[-1][0]!r} has a list property; strand PLY files "
                                 f"use scalar properties only")
            if len(tok) != 3 or tok[1] not in _PLY_TYPES:
                raise GroomError(f"{name}: unsupported PLY property line {ln!r}")
            props = elements[-1][2]
            if any(p[0] == tok[2] for p in props):
                raise GroomError(f"{name}: property {tok[2]!r} of {elements[-1][0]!r} is declared twice")
            props.append((tok[2], _PLY_TYPES[tok[1]]))
        else:
            raise GroomError(f"{name}: unknown PLY header line {ln!r}")
    if fmt is None:
        raise GroomError(f"{name}: the PLY header has no format line")
    if fmt != ["binary_little_endian", "1.0"]:
        raise GroomError(f"{name}: PLY format {' '.join(fmt)!r} is not supported; write binary_little_endian 1.0")
    out = []
    for ename, count, props in elements:
        if not props:
            raise GroomError(f"{name}: element {ename!r} has no properties")
        out.append((ename, count, np.dtype([(p, t) for p, t in props])))
    return out, nl + 1


def _parse_ply(buf: bytes, name: str) -> _Raw:
    elements, off = _parse_ply_header(buf, name)
    size = len(buf)
    data: dict[str, np.ndarray] = {}
    for ename, count, dt in elements:
        nbytes = count * dt.itemsize
        if off + nbytes > size:
            raise GroomError(f"{name}: header says {count} {ename} records of {dt.itemsize} bytes, which need "
                             f"{nbytes} bytes, but only {max(size - off, 0)} remain")
        data[ename] = np.frombuffer(buf, dt, count, off)
        off += nbytes
    warnings = [f"{size - off} trailing bytes ignored"] if off < size else []
    for ename in data:
        if ename not in ("vertex", "strand", "edge"):
            warnings.append(f"element {ename!r} ignored")
    if "vertex" not in data or not {"x", "y", "z"} <= set(data["vertex"].dtype.names or ()):
        raise GroomError(f"{name}: needs a 'vertex' element with x, y and z")
    if "strand" not in data or "nsegs" not in (data["strand"].dtype.names or ()):
        raise GroomError(f"{name}: needs a 'strand' element with an 'nsegs' property (vertices are stored strand "
                         f"after strand, nsegs + 1 each)")
    vert, strand = data["vertex"], data["strand"]
    if strand.dtype["nsegs"].kind not in "iu":
        raise GroomError(f"{name}: 'nsegs' must be an integer property")
    nsegs = strand["nsegs"].astype(np.int64)
    if len(nsegs) == 0:
        raise GroomError(f"{name}: the file holds 0 strands")
    if (nsegs < 0).any():
        raise GroomError(f"{name}: strand {int(np.argmax(nsegs < 0))} has a negative segment count")
    counts = nsegs + 1
    total = int(counts.sum())
    if total != len(vert):
        raise GroomError(f"{name}: strands add up to {total} vertices but the vertex element has {len(vert)}")
    if "edge" in data:
        _check_ply_edges(data["edge"], counts, name)
    points = np.stack([vert["x"], vert["y"], vert["z"]], axis=1)
    colors = None
    if {"red", "green", "blue"} <= set(vert.dtype.names or ()):
        colors = np.stack([vert["red"], vert["green"], vert["blue"]], axis=1).astype(np.float64)
        if vert.dtype["red"].kind in "iu":
            colors /= 255.0
    thickness = vert["thickness"].astype(np.float64) if "thickness" in (vert.dtype.names or ()) else None
    return _Raw(points, counts, thickness, colors, warnings=warnings)


def _check_ply_edges(edge: np.ndarray, counts: np.ndarray, name: str) -> None:
    """Edges must be exactly the consecutive pairs inside each strand; anything else is a topology vfiber
    would silently misread as strands, so it is rejected."""
    names = edge.dtype.names or ()
    if not {"vertex1", "vertex2"} <= set(names):
        raise GroomError(f"{name}: the 'edge' element needs vertex1 and vertex2 properties")
    nseg_total = int(counts.sum() - len(counts))
    if len(edge) != nseg_total:
        raise GroomError(f"{name}: {len(edge)} edges but the strands have {nseg_total} segments")
    total = int(counts.sum())
    first = np.arange(total, dtype=np.int64)
    is_tip = np.zeros(total, bool)
    is_tip[np.cumsum(counts) - 1] = True
    expected = first[~is_tip]
    if not (np.array_equal(edge["vertex1"], expected) and np.array_equal(edge["vertex2"], expected + 1)):
        raise GroomError(f"{name}: edges are not the consecutive vertex pairs of each strand; only the strand "
                         f"layout (vertices strand after strand) is supported")


_PARSERS = {"hair": _parse_hair, "data": _parse_data, "tfx": _parse_tfx, "ply": _parse_ply}


def _sniff(buf: bytes, suffix: str, name: str) -> tuple[str, list[str]]:
    """Format from the magic bytes where the format has any, else from the extension."""
    by_ext = _EXTENSIONS.get(suffix.lower())
    by_magic = None
    if buf[:4] == b"HAIR":
        by_magic = "hair"
    elif buf[:3] == b"ply" and buf[3:4] in (b"\n", b"\r"):
        by_magic = "ply"
    if by_magic and by_ext and by_magic != by_ext:
        # .data/.tfx cannot legitimately start with these magics (the count/version they would encode is
        # absurd), so the content is the better witness.
        return by_magic, [f"content is {by_magic}, not {by_ext} as the extension says"]
    fmt = by_magic or by_ext
    if fmt is None:
        raise GroomError(f"{name}: unknown groom format (extension {suffix!r}); vfiber reads "
                         + ", ".join(_EXTENSIONS))
    return fmt, []
