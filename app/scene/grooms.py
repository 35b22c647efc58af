"""Load real groom files and turn their strands into guide polylines for hair cylinders.

Four binary formats are read: Cem Yuksel ``.hair``, USC-HairSalon ``.data``, AMD TressFX 4 ``.tfx`` and strand
``.ply`` (binary little-endian, ``vertex``/``strand``/``edge`` elements). Every one of them is untrusted input:
a groom file comes from whoever made it, so each count in a header is checked against the number of bytes the
file really holds *before* anything is allocated from it. A corrupt file therefore costs at most memory
proportional to its own size and ends in a :class:`GroomError` that names the file and what is wrong.

Strands that cannot become a hair (fewer than two vertices, a non-finite coordinate, zero length) are dropped
and counted in :attr:`Groom.skipped` rather than failing the whole file: real exports contain a few of them.

The renderer is Z-up, so every groom is rotated on load so that the file's up axis becomes +Z; ``up="auto"``
guesses that axis from the strands themselves (see :func:`guess_up`).
"""

from __future__ import annotations

import math
import os
import stat
import struct
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

import numpy as np

from ..params import Params
from .containers import Scene, orthonormal_x

if TYPE_CHECKING:
    from .groom_info import GroomScene

__all__ = [
    "FORMATS", "MAX_FILE_BYTES", "SEGMENT_TOLERANCE", "UP_CHOICES", "Groom", "GroomError", "Guides",
    "MAX_TURN_DEG", "auto_segments", "chord_errors", "container_rows", "default_radius", "groom_scene",
    "guess_up", "joint_turns", "load_groom",
    "parse_groom", "resample", "resample_many", "scene_from_groom", "strands_to_guides", "up_rotation",
]

MAX_FILE_BYTES = 2 * 1024**3
"""Largest groom file accepted. The biggest production grooms are a few hundred MB; anything larger is far
more likely to be the wrong file, and the parse holds a few copies of the point data in memory."""

FORMATS = ("hair", "data", "tfx", "ply")
_EXTENSIONS = {".hair": "hair", ".data": "data", ".tfx": "tfx", ".ply": "ply"}

UP_CHOICES = ("auto", "x", "-x", "y", "-y", "z", "-z")
"""Values of ``up``: the axis *of the file* that points up (it becomes +Z). ``"-x"`` means the file's -X is
up, i.e. gravity along +X. The parameter table offers a subset; all six signed axes work here."""

# Formats whose authoring tools fix the orientation: TressFX assets come from Y-up game/DCC pipelines and the
# USC-HairSalon database is Y-up by construction. .hair and .ply carry no such convention.
_FORMAT_UP = {"tfx": "y", "data": "y"}

# Bound on the float64 elements one vectorised step may create at once (2 MiB), so clustering and nearest-
# neighbour searches on 100k+ strands stay in bounded memory whatever the groom size; chunks this small also
# stay in cache, which measured 7x faster than 32 MiB chunks on harolongo's roots.
_CHUNK_ELEMS = 1 << 18


class GroomError(ValueError):
    """A groom file is unusable: the message starts with the file's name and says what is wrong."""


@dataclass
class Groom:
    """Strands of one groom file, already rotated to Z-up and scaled.

    ``strands`` are views into one packed float64 array (every strand has at least two vertices, finite
    coordinates and a non-zero length). ``thickness`` and ``colors`` are per-vertex arrays parallel to
    ``strands`` when the file stores them, else None (header defaults, if any, are in ``meta``).
    """

    path: Path
    format: str
    strands: list[np.ndarray]
    thickness: list[np.ndarray] | None = None
    colors: list[np.ndarray] | None = None
    skipped: dict[str, int] = field(default_factory=dict)
    up: str = "z"                      # the file axis that was rotated onto +Z
    up_reason: str = ""                # why: "given", or the evidence ``guess_up`` used
    scale: float = 1.0
    meta: dict[str, object] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    @property
    def n_strands(self) -> int:
        return len(self.strands)

    @property
    def n_vertices(self) -> int:
        return int(sum(len(s) for s in self.strands))

    def packed(self) -> tuple[np.ndarray, np.ndarray]:
        """All vertices as one (N, 3) array and the (n_strands + 1,) offsets where each strand starts."""
        counts = np.fromiter((len(s) for s in self.strands), np.int64, len(self.strands))
        offsets = np.zeros(len(counts) + 1, np.int64)
        np.cumsum(counts, out=offsets[1:])
        points = np.concatenate(self.strands) if self.strands else np.zeros((0, 3))
        return points, offsets

    def bbox(self) -> tuple[np.ndarray, np.ndarray]:
        """(min corner, max corner) of all vertices."""
        points, _ = self.packed()
        if len(points) == 0:
            return np.zeros(3), np.zeros(3)
        return points.min(axis=0), points.max(axis=0)

    def lengths(self) -> np.ndarray:
        """Arc length of every strand."""
        points, offsets = self.packed()
        seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
        sid = np.repeat(np.arange(self.n_strands), np.diff(offsets))
        inner = sid[1:] == sid[:-1]
        return np.bincount(sid[1:][inner], weights=seg[inner], minlength=self.n_strands)


# --------------------------------------------------------------------------------------------------------
# Raw parse result shared by the four formats, before skipping, rotation and splitting.

@dataclass
class _Raw:
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


# --------------------------------------------------------------------------------------------------------
# Orientation

_ROTATIONS = {
    # Proper rotations (det +1, so handedness is kept) taking the named file axis onto +Z.
    "z": ((1, 0, 0), (0, 1, 0), (0, 0, 1)),
    "-z": ((1, 0, 0), (0, -1, 0), (0, 0, -1)),
    "y": ((1, 0, 0), (0, 0, -1), (0, 1, 0)),
    "-y": ((1, 0, 0), (0, 0, 1), (0, -1, 0)),
    "x": ((0, 0, -1), (0, 1, 0), (1, 0, 0)),
    "-x": ((0, 0, 1), (0, 1, 0), (-1, 0, 0)),
}


def up_rotation(up: str) -> np.ndarray:
    """3x3 rotation R with world = R @ file that takes the file's ``up`` axis onto +Z."""
    if up not in _ROTATIONS:
        raise ValueError(f"up must be one of {', '.join(UP_CHOICES)}, not {up!r}")
    return np.array(_ROTATIONS[up], dtype=np.float64)


def guess_up(roots: np.ndarray, tips: np.ndarray, lengths: np.ndarray, bbox_diagonal: float,
             fmt: str | None = None) -> tuple[str, str]:
    """Which file axis is up, with a short reason, from strand roots, tips and arc lengths.

    Evidence: hair that hangs points *down*, so the length-weighted mean root-to-tip vector ``g`` is a
    gravity estimate (|g| <= 1; 1 means every strand is a straight drop). It is trusted as *clear* when one
    axis dominates (|g_k| >= 0.3 and at least twice the next component), and as *strong* when it is clear
    and the strands are long enough to hang at all (median length >= 0.1 x the groom's bbox diagonal).
    Short fur and styled spikes point along their skin normal, not along gravity: Ratboy's mohawk runs down
    the character's back with spikes swept along -Z, which would read as "Z up" by gravity alone.

    Decision: formats with a fixed convention (TressFX, USC-HairSalon: Y-up) keep it unless the evidence is
    strong and disagrees; formats without one (.hair, .ply) follow clear evidence, and otherwise are left
    as they are (Z-up, no rotation).
    """
    total = float(lengths.sum())
    g = (tips - roots).sum(axis=0) / total if total > 0 else np.zeros(3)
    mags = np.abs(g)
    order = np.argsort(mags)[::-1]
    k = int(order[0])
    clear = mags[k] >= 0.3 and mags[k] >= 2.0 * mags[order[1]]
    rel_len = float(np.median(lengths)) / bbox_diagonal if bbox_diagonal > 0 else 0.0
    strong = clear and rel_len >= 0.1
    by_data = ("-" if g[k] > 0 else "") + "xyz"[k]    # up is opposite to where the strands fall
    evidence = f"mean root-to-tip {np.round(g, 3).tolist()}, median length {rel_len:.3f} of the bbox diagonal"
    convention = _FORMAT_UP.get(fmt or "")
    if convention is not None:
        if strong and by_data != convention:
            return by_data, f"strands hang clearly along {by_data} up ({evidence}), overriding the {fmt} convention"
        agree = "agrees" if by_data == convention and clear else "is not strong enough to override it"
        return convention, f"{fmt} convention is {convention} up; the data {agree} ({evidence})"
    if clear:
        return by_data, f"strands hang along {by_data} up ({evidence})"
    return "z", f"no clear gravity direction, left Z-up ({evidence})"


# --------------------------------------------------------------------------------------------------------
# Loading

def load_groom(path: str | Path, up: str = "auto", scale: float = 1.0) -> Groom:
    """Read a groom file (.hair, .data, .tfx or .ply), rotate it so the file's ``up`` axis becomes +Z and
    multiply coordinates by ``scale``. Raises :class:`GroomError` for anything wrong with the file."""
    p = Path(path)
    _check_options(up, scale)
    buf = _read_regular_file(p)
    return parse_groom(buf, None, name=p.name, suffix=p.suffix, up=up, scale=scale, path=p)


_NOT_REGULAR = ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISSOCK, "a socket"),
                (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"))


def _read_regular_file(p: Path) -> bytes:
    """The bytes of a regular file of at most MAX_FILE_BYTES. A device or a FIFO reports st_size 0, so a
    size check alone would read /dev/zero until memory ran out or block on a pipe forever: anything but a
    regular file is refused before it is opened, and the read itself stops one byte past the limit."""
    if "\0" in str(p):
        shown = str(p.name).replace("\0", "\\0")
        raise GroomError(f"{shown}: the path contains a NUL byte, which no file name can")
    try:
        info = p.stat()  # follows symbolic links: a link to /dev/zero is a device
        for test, what in _NOT_REGULAR:
            if test(info.st_mode):
                raise GroomError(f"{p.name}: is {what}, not a regular groom file")
        if not stat.S_ISREG(info.st_mode):
            raise GroomError(f"{p.name}: is not a regular file")
        if info.st_size > MAX_FILE_BYTES:
            raise GroomError(f"{p.name}: {info.st_size} bytes is larger than the {MAX_FILE_BYTES}-byte limit "
                             "for grooms")
        # O_NONBLOCK: should the path turn into a FIFO between stat and open, open does not wait for a writer
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
        with os.fdopen(fd, "rb") as f:
            opened = os.fstat(f.fileno())
            if not stat.S_ISREG(opened.st_mode):
                raise GroomError(f"{p.name}: is not a regular file")
            # read() of n preallocates n bytes: ask for the file's size (+1 notices a file still growing)
            buf = f.read(min(opened.st_size, MAX_FILE_BYTES) + 1)
            if len(buf) > opened.st_size:
                buf += f.read(MAX_FILE_BYTES + 1 - len(buf))
    except OSError as exc:
        raise GroomError(f"{p.name}: cannot read the file ({exc.strerror or exc})") from exc
    if len(buf) > MAX_FILE_BYTES:
        raise GroomError(f"{p.name}: more than the {MAX_FILE_BYTES}-byte limit for grooms")
    return buf


def parse_groom(buf: bytes, fmt: str | None = None, *, name: str = "<groom>", suffix: str = "",
                up: str = "auto", scale: float = 1.0, path: Path | None = None) -> Groom:
    """Like :func:`load_groom` for bytes already in memory. ``fmt`` (one of :data:`FORMATS`) skips sniffing."""
    _check_options(up, scale)
    if len(buf) > MAX_FILE_BYTES:
        raise GroomError(f"{name}: {len(buf)} bytes is larger than the {MAX_FILE_BYTES}-byte limit for grooms")
    warnings: list[str] = []
    if fmt is None:
        fmt, warnings = _sniff(buf, suffix, name)
    elif fmt not in _PARSERS:
        raise ValueError(f"fmt must be one of {', '.join(FORMATS)}, not {fmt!r}")
    try:
        raw = _PARSERS[fmt](buf, name)
    except GroomError:
        raise
    except (ValueError, IndexError, struct.error, OverflowError) as exc:
        # A safety net so that a parser gap still surfaces as a GroomError; the fuzz tests look for this
        # wording, so a gap is found rather than hidden.
        raise GroomError(f"{name}: unexpected parser failure on this {fmt} file ({exc})") from exc
    raw.warnings[:0] = warnings
    return _finish(raw, name, fmt, up, scale, path if path is not None else Path(name))


def _check_options(up: str, scale: float) -> None:
    if up not in UP_CHOICES:
        raise ValueError(f"up must be one of {', '.join(UP_CHOICES)}, not {up!r}")
    if not (isinstance(scale, (int, float)) and math.isfinite(scale) and scale > 0):
        raise ValueError(f"scale must be a finite number > 0, not {scale!r}")


def _finish(raw: _Raw, name: str, fmt: str, up: str, scale: float, path: Path) -> Groom:
    """Drop strands that cannot be hairs (counting why), orient, scale and split into per-strand views."""
    counts = raw.counts.astype(np.int64)
    n_str = len(counts)
    # Work on (3, N) rows: reductions across xyz on an (N, 3) array are several times slower than
    # elementwise operations on three contiguous rows, and this runs on every vertex of every load.
    with np.errstate(invalid="ignore"):
        # Widening a signalling-NaN bit pattern (a corrupt float) raises the FP "invalid" flag; it is then
        # skipped as non-finite like any other NaN, so the warning would only be noise.
        rows = np.ascontiguousarray(np.asarray(raw.points).T, dtype=np.float64)
    sid = np.repeat(np.arange(n_str, dtype=np.int64), counts)    # strand id of each vertex
    fin = np.isfinite(rows)
    finite_v = fin[0] & fin[1] & fin[2]
    bad_per_strand = np.bincount(sid[~finite_v], minlength=n_str)
    # Segment lengths inside strands only; pairs that straddle two strands are masked out, and non-finite
    # coordinates are zeroed so their (skipped) strands cannot spread NaN or raise warnings.
    d = np.diff(np.where(finite_v, rows, 0.0), axis=1)
    seg = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    inner = sid[1:] == sid[:-1]
    length = np.bincount(sid[1:][inner], weights=seg[inner], minlength=n_str)

    reasons = (("no vertices", counts == 0), ("one vertex", counts == 1),
               ("non-finite", bad_per_strand > 0), ("zero length", length <= 0.0))
    keep = np.ones(n_str, bool)
    skipped: dict[str, int] = {}
    for reason, hit in reasons:
        hit = hit & keep
        if hit.any():
            skipped[reason] = int(hit.sum())
            keep &= ~hit
    if not keep.any():
        raise GroomError(f"{name}: none of the {n_str} strands is usable ({_describe(skipped)})")

    vmask = np.repeat(keep, counts)
    kcounts = counts[keep]
    krows = rows[:, vmask] if not keep.all() else rows
    ends = np.cumsum(kcounts)
    starts = ends - kcounts
    diag = float(np.linalg.norm(krows.max(axis=1) - krows.min(axis=1)))
    if up == "auto":
        axis, reason = guess_up(krows[:, starts].T, krows[:, ends - 1].T, length[keep], diag, fmt)
    else:
        axis, reason = up, "given"
    world = np.ascontiguousarray((up_rotation(axis) @ krows).T)
    if scale != 1.0:
        world *= scale
    # Plain slices of one packed array: views, no copies, and cheaper per strand than np.split.
    bounds = list(zip(starts.tolist(), ends.tolist()))

    def split(a: np.ndarray) -> list[np.ndarray]:
        return [a[i:j] for i, j in bounds]

    strands = split(world)
    thickness = split(np.asarray(raw.thickness, np.float64)[vmask] * scale) if raw.thickness is not None else None
    colors = split(np.asarray(raw.colors, np.float64)[vmask]) if raw.colors is not None else None
    return Groom(path=path, format=fmt, strands=strands, thickness=thickness, colors=colors, skipped=skipped,
                 up=axis, up_reason=reason, scale=float(scale), meta=raw.meta, warnings=raw.warnings)


def _describe(skipped: dict[str, int]) -> str:
    return ", ".join(f"{n} {reason}" for reason, n in skipped.items()) or "nothing skipped"


# --------------------------------------------------------------------------------------------------------
# Guides

def resample_many(strands: Sequence[np.ndarray], n_segments: int) -> np.ndarray:
    """Resample every strand to ``n_segments`` pieces equally spaced in arc length: (S, n_segments + 1, 3).

    All strands go through one ``np.interp`` per coordinate: strand i is parametrised on [2i, 2i + 1], so the
    parameter stays strictly increasing across strands and the gaps keep neighbours from blending.
    """
    if n_segments < 1:
        raise ValueError(f"n_segments must be >= 1, not {n_segments}")
    n = len(strands)
    if n == 0:
        return np.zeros((0, n_segments + 1, 3))
    counts = np.fromiter((len(s) for s in strands), np.int64, n)
    if (counts < 2).any():
        raise ValueError("every strand needs at least 2 vertices to be resampled")
    pts = np.concatenate([np.asarray(s, np.float64).reshape(-1, 3) for s in strands])
    sid = np.repeat(np.arange(n, dtype=np.int64), counts)
    ends = np.cumsum(counts)
    starts = ends - counts
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    seg[ends[:-1] - 1] = 0.0                        # the jump from one strand's tip to the next root
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    total = cum[ends - 1] - cum[starts]
    if not (total > 0).all():
        raise ValueError(f"strand {int(np.argmin(total > 0))} has zero length and cannot be resampled")
    # Clipping keeps t non-decreasing within a strand despite rounding in cum / total; np.interp then needs
    # it strictly increasing, so only the first vertex of each run of equal t (duplicates) is used. Strand i
    # lives on [2i, 2i + 1], which keeps the whole sequence increasing and neighbours from blending.
    t = np.minimum((cum - cum[starts][sid]) / total[sid], 1.0)
    t[ends - 1] = 1.0
    use = np.ones(len(t), bool)
    use[1:] = t[1:] > t[:-1]
    use[starts] = True
    kt = t[use] + 2.0 * sid[use]
    kp = pts[use]
    q = (2.0 * np.arange(n)[:, None] + np.linspace(0.0, 1.0, n_segments + 1)[None, :]).ravel()
    out = np.empty((n * (n_segments + 1), 3))
    for c in range(3):
        out[:, c] = np.interp(q, kt, kp[:, c])
    out = out.reshape(n, n_segments + 1, 3)
    out[:, 0] = pts[starts]
    out[:, -1] = pts[ends - 1]
    return out


def resample(strand: np.ndarray, n_segments: int) -> np.ndarray:
    """One strand resampled to ``n_segments`` equal arc-length pieces: (n_segments + 1, 3), same endpoints."""
    return resample_many([strand], n_segments)[0]


def _nearest_distances(points: np.ndarray, queries: np.ndarray, exclude: np.ndarray, tiny: float) -> np.ndarray:
    """Distance from each query to its nearest point other than itself (and other than exact duplicates,
    closer than ``tiny``: two strands sharing a root say nothing about spacing). Chunked brute force."""
    out = np.empty(len(queries))
    p2 = (points**2).sum(axis=1)
    step = max(1, _CHUNK_ELEMS // max(len(points), 1))
    for a in range(0, len(queries), step):
        q = queries[a:a + step]
        d2 = (q**2).sum(axis=1)[:, None] - 2.0 * q @ points.T + p2[None, :]
        d2[np.arange(len(q)), exclude[a:a + step]] = np.inf
        d2[d2 <= tiny * tiny] = np.inf
        out[a:a + step] = np.sqrt(np.maximum(d2.min(axis=1), 0.0))
    return out


def default_radius(roots: np.ndarray, seed: int = 0, max_queries: int = 1024) -> float:
    """Container radius from root spacing: 0.75 x the median distance from a root to its nearest neighbour,
    so neighbouring cylinders overlap a little and the scalp is covered without gaps.

    The median comes from at most ``max_queries`` seeded sample roots against all roots, which bounds time
    and memory for very large grooms while staying a stable estimate. Falls back to 0.5 % of the root spread
    (or 1.0 for a single root at the origin of nothing) when no two distinct roots exist.
    """
    roots = np.asarray(roots, np.float64).reshape(-1, 3)
    n = len(roots)
    spread = float(np.linalg.norm(roots.max(axis=0) - roots.min(axis=0))) if n else 0.0
    fallback = 0.005 * spread if spread > 0 else 1.0
    if n < 2:
        return fallback
    rng = np.random.default_rng(seed)
    idx = np.arange(n) if n <= max_queries else np.sort(rng.choice(n, max_queries, replace=False))
    d = _nearest_distances(roots, roots[idx], idx, 1e-9 * spread)
    d = d[np.isfinite(d)]
    return 0.75 * float(np.median(d)) if len(d) else fallback


def _kmeans(x: np.ndarray, k: int, seed: int, max_iter: int = 50) -> np.ndarray:
    """Seeded k-means (k-means++ start when affordable) returning a label per row, in bounded memory."""
    n = len(x)
    rng = np.random.default_rng(seed)
    x2 = (x**2).sum(axis=1)

    def dist2_to(c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        labels = np.empty(n, np.int64)
        best = np.empty(n)
        c2 = (c**2).sum(axis=1)
        step = max(1, _CHUNK_ELEMS // max(len(c), 1))
        for a in range(0, n, step):
            d2 = x2[a:a + step, None] - 2.0 * x[a:a + step] @ c.T + c2[None, :]
            labels[a:a + step] = d2.argmin(axis=1)
            best[a:a + step] = d2[np.arange(len(d2)), labels[a:a + step]]
        return labels, np.maximum(best, 0.0)

    if n * k <= 50_000_000:
        # k-means++: spread the starting centres so small, far clusters (a stray lock) get their own guide.
        centres = np.empty((k, x.shape[1]))
        centres[0] = x[rng.integers(n)]
        d2 = ((x - centres[0]) ** 2).sum(axis=1)
        for j in range(1, k):
            s = d2.sum()
            i = int(rng.choice(n, p=d2 / s)) if s > 0 else int(rng.integers(n))
            centres[j] = x[i]
            d2 = np.minimum(d2, ((x - x[i]) ** 2).sum(axis=1))
    else:
        centres = x[rng.choice(n, k, replace=False)].copy()
    labels = np.full(n, -1, np.int64)
    for _ in range(max_iter):
        new, best = dist2_to(centres)
        if np.array_equal(new, labels):
            break
        labels = new
        sizes = np.bincount(labels, minlength=k)
        for c in range(x.shape[1]):
            centres[:, c] = np.bincount(labels, weights=x[:, c], minlength=k)
        empty = sizes == 0
        centres[~empty] /= sizes[~empty, None]
        if empty.any():
            # Re-seed an empty cluster at the worst-fitting strands so k guides really are made.
            far = np.argsort(best)[::-1][: int(empty.sum())]
            centres[empty] = x[far]
            labels[far] = np.flatnonzero(empty)
    return labels


def _point_polyline_distance(p: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Distances from points p (M, P, 3) to polylines poly (M, Q, 3): (M, P)."""
    a, b = poly[:, None, :-1], poly[:, None, 1:]             # (M, 1, Q-1, 3)
    ab = b - a
    ap = p[:, :, None, :] - a                                  # (M, P, Q-1, 3)
    denom = np.maximum((ab**2).sum(axis=-1), 1e-300)
    t = np.clip((ap * ab).sum(axis=-1) / denom, 0.0, 1.0)
    d = np.linalg.norm(ap - t[..., None] * ab, axis=-1)
    return d.min(axis=-1)


class Guides(tuple):
    """``(polylines, radii)`` — unpacks like a pair — plus ``dropped`` (reason -> strand count) and
    ``labels`` (guide index of every groom strand, -1 where the strand was dropped)."""

    dropped: dict[str, int]
    labels: np.ndarray

    def __new__(cls, polylines: list[np.ndarray], radii: np.ndarray, dropped: dict[str, int],
                labels: np.ndarray) -> "Guides":
        self = super().__new__(cls, (polylines, radii))
        self.dropped = dropped
        self.labels = labels
        return self

    @property
    def polylines(self) -> list[np.ndarray]:
        return self[0]

    @property
    def radii(self) -> np.ndarray:
        return self[1]


def strands_to_guides(groom: Groom, segments: int = 8, radius: float | None = None, cluster: int = 0,
                      seed: int = 0, min_length: float | None = None) -> Guides:
    """Guide polylines (each ``segments + 1`` points) and one container radius per guide.

    ``cluster=0``: every strand is a guide and every radius is ``radius`` or :func:`default_radius` of the
    roots. ``cluster=N``: N guides from k-means over resampled strands; a guide is its cluster's mean strand
    and its radius covers 90 % of the members (each member's farthest point from the guide), never less
    than ``radius`` or the default.

    Strands shorter than ``min_length`` (default 1e-3 of the groom's bbox diagonal: sub-pixel whenever the
    whole groom is in view, so a container there is only a blob) are dropped and counted.
    """
    if segments < 1:
        raise ValueError(f"segments must be >= 1, not {segments}")
    if cluster < 0:
        raise ValueError(f"cluster must be >= 0, not {cluster}")
    if radius is not None and not (math.isfinite(radius) and radius > 0):
        raise ValueError(f"radius must be a finite number > 0, not {radius!r}")
    lo, hi = groom.bbox()
    diag = float(np.linalg.norm(hi - lo))
    if min_length is None:
        min_length = 1e-3 * diag
    lengths = groom.lengths()
    keep = lengths >= min_length
    dropped = {"shorter than min_length": int((~keep).sum())} if not keep.all() else {}
    if not keep.any():
        raise GroomError(f"{groom.path.name}: no strand is at least {min_length:g} long")
    kept = [s for s, k in zip(groom.strands, keep) if k]
    res = resample_many(kept, segments)
    floor = float(radius) if radius is not None else default_radius(res[:, 0], seed=seed)
    labels = np.full(groom.n_strands, -1, np.int64)
    kept_idx = np.flatnonzero(keep)
    if cluster == 0 or cluster >= len(kept):
        labels[kept_idx] = np.arange(len(kept))
        return Guides(list(res), np.full(len(kept), floor), dropped, labels)

    n, m = res.shape[0], res.shape[1]
    # Features are the whole resampled strand, so the cluster mean *is* the mean strand; the root is weighted
    # to count as much as the rest of the strand together, keeping each guide anchored where its members grow.
    w = np.ones((m, 1))
    w[0] = math.sqrt(m)
    feats = (res * w).reshape(n, -1)
    lab = _kmeans(feats, cluster, seed)
    sizes = np.bincount(lab, minlength=cluster)
    guides = np.empty((cluster, m, 3))
    for c in range(3):
        flat = res[:, :, c]
        for j in range(m):
            guides[:, j, c] = np.bincount(lab, weights=flat[:, j], minlength=cluster)
    guides /= np.maximum(sizes, 1)[:, None, None]
    # Each member's farthest point from its guide polyline; chunked so (members x points x segments) stays small.
    far = np.empty(n)
    step = max(1, _CHUNK_ELEMS // (m * m * 3))
    for a in range(0, n, step):
        far[a:a + step] = _point_polyline_distance(res[a:a + step], guides[lab[a:a + step]]).max(axis=1)
    order = np.lexsort((far, lab))
    sorted_far = far[order]
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    pos = starts + 0.9 * np.maximum(sizes - 1, 0)
    lo_i = np.floor(pos).astype(np.int64)
    hi_i = np.minimum(lo_i + 1, starts + np.maximum(sizes - 1, 0))
    frac = pos - lo_i
    safe = sizes > 0
    p90 = np.zeros(cluster)
    p90[safe] = (sorted_far[lo_i[safe]] * (1 - frac[safe]) + sorted_far[hi_i[safe]] * frac[safe])
    radii = np.maximum(p90, floor)
    # k-means re-seeds empty clusters, but a cluster can still end empty when strands coincide exactly.
    used = np.flatnonzero(sizes > 0)
    remap = np.full(cluster, -1, np.int64)
    remap[used] = np.arange(len(used))
    labels[kept_idx] = remap[lab]
    return Guides(list(guides[used]), radii[used], dropped, labels)


# --------------------------------------------------------------------------------------------------------
# Scene: guides -> containers

def _rotate_minimally_many(v: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``containers._rotate_minimally`` on rows: v, a, b are (S, 3); a and b unit. Same branches."""
    c = (a * b).sum(axis=1, keepdims=True)
    axis = np.cross(a, b)
    s = np.linalg.norm(axis, axis=1, keepdims=True)
    turned = s[:, 0] >= 1e-12
    out = v.copy()
    if turned.any():
        ax = axis[turned] / s[turned]
        vt, ct, st = v[turned], c[turned], s[turned]
        out[turned] = vt * ct + np.cross(ax, vt) * st + ax * (ax * vt).sum(axis=1, keepdims=True) * (1 - ct)
    back = ~turned & (c[:, 0] <= 0)
    if back.any():
        # A 180 degree turn: mirror about an axis perpendicular to a, continuous with v where possible.
        ax = np.cross(a[back], v[back])
        n = np.linalg.norm(ax, axis=1, keepdims=True)
        fallback = orthonormal_x(a[back])
        ax = np.where(n > 0, ax / np.where(n > 0, n, 1.0), fallback)
        out[back] = 2 * (v[back] * ax).sum(axis=1, keepdims=True) * ax - v[back]
    return out


def _bisectors(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``containers._bisector`` on rows."""
    n = a + b
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.where(length < 1e-9, a, n / np.where(length < 1e-9, 1.0, length))


def container_rows(guides: np.ndarray, radii: np.ndarray, taper: float, origin: np.ndarray) -> np.ndarray:
    """The rows ``Scene.from_polylines`` makes, for S guides of equal point count at once: (S * (M-1), 20).

    ``guides`` is (S, M, 3) float64 with no zero-length piece (the caller checks). The frame, joint-plane
    and taper arithmetic is ``containers.Scene.from_polylines`` step for step, vectorised across guides:
    the per-segment Python loop there takes 12 s for harolongo's 63k segments, this takes a few hundredths.
    ``tests/test_groom_render.py`` holds the two equal on real and adversarial guides.
    """
    from .containers import SEGMENT_FLOATS

    S, M = guides.shape[:2]
    seglen = np.linalg.norm(np.diff(guides, axis=1), axis=2)                  # (S, M-1)
    v = np.concatenate([np.zeros((S, 1)), np.cumsum(seglen, axis=1)], axis=1) / seglen.sum(axis=1)[:, None]
    r = np.asarray(radii, np.float64)[:, None] * (1.0 - taper * v)            # (S, M)
    axes = np.diff(guides, axis=1) / seglen[:, :, None]                      # (S, M-1, 3)
    rows = np.empty((S, M - 1, SEGMENT_FLOATS))
    fx = orthonormal_x(axes[:, 0])
    for k in range(M - 1):
        a = axes[:, k]
        if k > 0:
            fx = _rotate_minimally_many(fx, axes[:, k - 1], a)
            fx -= a * (fx * a).sum(axis=1, keepdims=True)
            fx /= np.linalg.norm(fx, axis=1, keepdims=True)
        rows[:, k, 0:3] = guides[:, k] - origin
        rows[:, k, 3] = r[:, k]
        rows[:, k, 4:7] = guides[:, k + 1] - origin
        rows[:, k, 7] = r[:, k + 1]
        rows[:, k, 8:11] = a if k == 0 else _bisectors(axes[:, k - 1], a)
        rows[:, k, 11] = v[:, k]
        rows[:, k, 12:15] = a if k == M - 2 else _bisectors(a, axes[:, k + 1])
        rows[:, k, 15] = v[:, k + 1]
        rows[:, k, 16:19] = fx
        rows[:, k, 19] = np.arange(S)
    return rows.reshape(-1, SEGMENT_FLOATS)


SEGMENT_TOLERANCE = 0.5
"""Automatic segment count: the guide may leave the strand it stands for by at most this fraction of the
container radius, for 95 % of strands. Below one radius the strand stays inside its own fiber cloud; half a
radius keeps it off the rim, where a container's outer ring is all that covers it."""

MAX_TURN_DEG = 120.0
"""Automatic segment count: no joint of any guide may turn by more than this. Neighbouring containers meet
on the bisecting (miter) plane, which leans ``radius * tan(turn / 2)`` past the joint: 1.7 radii at 120
degrees, but 8.6 radii at Curly_100's 167-degree fold with 3 segments, a wedge of fibers far from any
strand. Finer guides turn less per joint."""

_AUTO_SEGMENTS = (1, 2, 3, 4, 5, 6, 8, 10, 12, 16, 20, 24, 32, 40, 48, 64)
_AUTO_SAMPLE_VERTICES = 1 << 14     # strand vertices measured per candidate count: bounds the auto search
_ROW_CHUNK = 1 << 16                # guides turned into container rows per vectorised step


def chord_errors(polylines: Sequence[np.ndarray], n_segments: int) -> np.ndarray:
    """How far each polyline's vertices get from the polyline resampled to ``n_segments``: (len,) maxima."""
    res = resample_many(polylines, n_segments)
    counts = np.fromiter((len(q) for q in polylines), np.int64, len(polylines))
    pts = np.concatenate([np.asarray(q, np.float64) for q in polylines])
    sid = np.repeat(np.arange(len(polylines)), counts)
    out = np.zeros(len(polylines))
    step = max(1, _CHUNK_ELEMS // (4 * (n_segments + 1)))
    for a in range(0, len(pts), step):
        d = _point_polyline_distance(pts[a:a + step, None], res[sid[a:a + step]])[:, 0]
        np.maximum.at(out, sid[a:a + step], d)
    return out


def joint_turns(guides: np.ndarray) -> np.ndarray:
    """Turn angle in degrees at every inner joint of guides (S, M, 3): (S, M - 2)."""
    d = np.diff(guides, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        d = d / np.linalg.norm(d, axis=2, keepdims=True)
        c = np.nan_to_num((d[:, 1:] * d[:, :-1]).sum(axis=2), nan=1.0)
    return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))


def _joints_ok(polylines: Sequence[np.ndarray], n_segments: int) -> bool:
    """Every guide resampled to ``n_segments`` has pieces of non-zero length (a strand that comes back to
    where it was cannot be a container there) and joints within :data:`MAX_TURN_DEG`. In chunks of guides,
    stopping at the first failure, so the search stays within bounded memory on any groom."""
    for a in range(0, len(polylines), _ROW_CHUNK):
        guides = resample_many(polylines[a:a + _ROW_CHUNK], n_segments)
        if not (np.linalg.norm(np.diff(guides, axis=1), axis=2) > 0).all():
            return False
        if n_segments > 1 and joint_turns(guides).max() > MAX_TURN_DEG:
            return False
    return True


def auto_segments(polylines: Sequence[np.ndarray], radii: np.ndarray, seed: int = 0) -> tuple[int, float, str]:
    """(segments, p95 error in radii, reason): the fewest segments in ``_AUTO_SEGMENTS`` whose resampled
    guides stay within :data:`SEGMENT_TOLERANCE` radii of the polylines they replace (95th percentile over
    a seeded sample) and turn by at most :data:`MAX_TURN_DEG` at every joint (all guides). Never more than
    the polylines' own segment count (more cannot follow them closer) nor 64; when no count meets both,
    that cap.
    """
    counts = np.fromiter((len(q) for q in polylines), np.int64, len(polylines))
    cap = int(min(64, max(1, counts.max() - 1)))
    order = np.random.default_rng(seed).permutation(len(polylines))
    take = order[: max(1, int(np.searchsorted(np.cumsum(counts[order]), _AUTO_SAMPLE_VERTICES, "right")))]
    sample = [polylines[i] for i in take]
    r = np.asarray(radii, np.float64)[take]
    p95 = math.inf
    for n in [c for c in _AUTO_SEGMENTS if c < cap] + [cap]:
        p95 = float(np.percentile(chord_errors(sample, n) / r, 95))
        if p95 > SEGMENT_TOLERANCE:
            continue
        if _joints_ok(polylines, n):
            return n, p95, (f"auto: the fewest that keep 95% of {len(sample):,} sampled strands within "
                            f"{SEGMENT_TOLERANCE} radii of their guide and every joint within {MAX_TURN_DEG:g} "
                            f"degrees")
    return cap, p95, (f"auto: no count up to the strands' own {cap} keeps them within {SEGMENT_TOLERANCE} "
                      f"radii of their guide and every joint within {MAX_TURN_DEG:g} degrees, so {cap}")


def _scene_rows(guides: np.ndarray, radii: np.ndarray, taper: float, name: str) -> tuple[np.ndarray, np.ndarray]:
    """float32 container rows and the float64 origin for guides (S, M, 3); ``Scene.from_polylines`` when a
    guide has a zero-length piece (it drops those points, the vectorised path cannot)."""
    from .containers import SEGMENT_FLOATS

    lo, hi = guides.reshape(-1, 3).min(axis=0), guides.reshape(-1, 3).max(axis=0)
    origin = 0.5 * (lo + hi)
    S, M = guides.shape[:2]
    with np.errstate(over="ignore", invalid="ignore"):
        if not (np.linalg.norm(np.diff(guides, axis=1), axis=2) > 0).all():
            rows = Scene.from_polylines(list(guides), radii, taper=taper, origin=origin).segments
        else:
            rows = np.empty((S * (M - 1), SEGMENT_FLOATS), np.float32)
            for a in range(0, S, _ROW_CHUNK):
                part = container_rows(guides[a:a + _ROW_CHUNK], radii[a:a + _ROW_CHUNK], taper, origin)
                part[:, 19] += a
                rows[a * (M - 1):a * (M - 1) + len(part)] = part
    if len(rows) == 0:
        raise GroomError(f"{name}: no usable strands: every guide comes back to its root at {M - 1} segments, "
                         f"so no container is left; set scene.segments higher")
    if not np.isfinite(rows).all():
        raise GroomError(f"{name}: coordinates are too large for the renderer's float32 containers after "
                         f"centring (extent {np.round(hi - lo, 3).tolist()}); check scene.groom_scale")
    return rows, origin


def groom_scene(groom: Groom, p: Params, seconds: dict[str, float] | None = None) -> "GroomScene":
    """Containers for a loaded groom under parameters ``p`` (see :func:`scene_from_groom`)."""
    from .containers import MAX_GUIDES
    from .groom_info import GroomScene, GroomSource

    name = groom.path.name
    seconds = dict(seconds or {})
    t0 = time.perf_counter()
    given = p["scene.segments"] if p["scene.segments"] > 1 else None
    cluster = p["scene.groom_cluster"]
    try:
        # Drops and the root-spacing radius; one segment is the cheapest resampling that yields them.
        base = strands_to_guides(groom, 1, seed=p["scene.seed"])
    except GroomError as exc:
        raise GroomError(f"{name}: no usable strands: {str(exc).split(': ', 1)[-1]}") from None
    kept = np.flatnonzero(base.labels >= 0)
    floor = float(base.radii[0])
    radius_reason = "0.75 x the median distance between neighbouring roots (scene.radius is not used for grooms)"
    if cluster and cluster < len(kept):
        # Cluster at the strands' own resolution; the guides are then resampled like strands would be.
        counts = np.fromiter((len(groom.strands[i]) for i in kept), np.int64, len(kept))
        fine_n = int(min(64, counts.max() - 1))
        guides = strands_to_guides(groom, fine_n, cluster=cluster, seed=p["scene.seed"])
        fine, radii = list(guides.polylines), np.asarray(guides.radii)
        radius_reason = (f"covers 90% of each cluster's strands, at least the root-spacing radius {floor:.4g} "
                         f"(scene.radius is not used for grooms)")
        cluster_used = cluster
    else:
        fine, radii = [groom.strands[i] for i in kept], np.full(len(kept), floor)
        cluster_used = 0
    if len(fine) > MAX_GUIDES:
        raise GroomError(f"{name}: {len(fine):,} guides is more than the renderer's {MAX_GUIDES:,}; set "
                         f"scene.groom_cluster to make fewer")
    if given:
        n = given
        p95 = float(np.percentile(chord_errors(fine, n) / radii, 95))
        reason = f"scene.segments = {n}"
    else:
        n, p95, reason = auto_segments(fine, radii, seed=p["scene.seed"])
        reason += " (scene.segments = 1 means auto for grooms)"
    # Polylines that already have n segments are used as they are: resampling could only move their points.
    same = all(len(q) == n + 1 for q in fine)
    polylines = np.stack(fine) if same else resample_many(fine, n)
    if same:
        p95 = 0.0
    native = same and not cluster_used          # the guides are the file's own vertices
    warnings = list(groom.warnings)
    folded = int((~(np.linalg.norm(np.diff(polylines, axis=1), axis=2) > 0).all(axis=1)).sum())
    if folded:
        warnings.append(f"{folded:,} guides have a zero-length piece at {n} segments (a strand that comes back "
                        f"to where it was); those pieces make no container")
    turns = joint_turns(polylines)
    sharp = int((turns > MAX_TURN_DEG).sum())
    if sharp:
        lean = math.tan(math.radians(min(float(turns.max()), 179.0)) / 2)
        warnings.append(f"{sharp:,} joints turn by more than {MAX_TURN_DEG:g} degrees (up to {turns.max():.0f}); "
                        f"their containers lean up to {lean:.1f} radii past the joint")
    seconds["guides"] = time.perf_counter() - t0
    t1 = time.perf_counter()
    rows, origin = _scene_rows(polylines, radii, p["scene.taper"], name)
    seconds["containers"] = time.perf_counter() - t1
    dropped = dict(base.dropped)
    source = GroomSource(
        path=groom.path, format=groom.format, strands_in_file=groom.n_strands + sum(groom.skipped.values()),
        strands=groom.n_strands, vertices=groom.n_vertices, skipped=dict(groom.skipped), dropped=dropped,
        up=groom.up, up_reason=groom.up_reason, scale=groom.scale, bbox=groom.bbox(), cluster=cluster_used,
        cluster_requested=cluster,
        guides=len(polylines), segments=n, segments_reason=reason, native=native, chord_p95=p95,
        radius_reason=radius_reason, radii=radii, seconds=seconds, warnings=warnings,
        max_turn=float(turns.max()) if turns.size else 0.0)
    return GroomScene(rows, origin, groom.path.stem, len(polylines), source=source, params=p)


def scene_from_groom(p: Params) -> "GroomScene":
    """The scene of ``scene.groom_file``: load (``scene.groom_up``, ``scene.groom_scale``), build guides
    (``scene.groom_cluster``, ``scene.segments``, ``scene.seed``) and containers (``scene.taper``).

    Guides: one per strand, or ``scene.groom_cluster`` k-means clusters of strands (the thesis's hybrid: few
    thick containers, many fibers each). Segments: ``scene.segments`` when it is more than 1; at 1, the
    default, it is chosen per groom (:func:`auto_segments`), because one straight segment from root to tip
    never contains a real strand. Guides are the file's own vertices whenever every strand already has
    exactly that many segments. Radius: from root spacing (clusters: enough for their members);
    ``scene.radius`` is the generators' and is not used. Raises :class:`GroomError` for anything wrong with
    the file, including a file without one usable strand.
    """
    t0 = time.perf_counter()
    path = Path(p["scene.groom_file"])
    try:
        groom = load_groom(path, up=p["scene.groom_up"], scale=p["scene.groom_scale"])
    except GroomError as exc:  # the loaders name the file by its base name; a person needs the whole path
        text = str(exc)
        if text.startswith(f"{path.name}:") and str(path) != path.name:
            raise GroomError(f"{path}{text[len(path.name):]}") from None
        raise
    return groom_scene(groom, p, {"load": time.perf_counter() - t0})
