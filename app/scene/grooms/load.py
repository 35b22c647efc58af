"""Loading: read a groom file safely, parse it with its format's reader, drop the strands that cannot be
hairs, orient and scale.

Strands that cannot become a hair (fewer than two vertices, a non-finite coordinate, zero length) are dropped
and counted in :attr:`Groom.skipped` rather than failing the whole file: real exports contain a few of them.
A corrupt file costs at most memory proportional to its own size and ends in a :class:`GroomError`.
"""

from __future__ import annotations

import math
import os
import stat
import struct
from pathlib import Path

import numpy as np

from .formats import _PARSERS, FORMATS, _Raw, _sniff
from .groom import Groom, GroomError
from .orient import UP_CHOICES, guess_up, up_rotation

MAX_FILE_BYTES = 2 * 1024**3
"""Largest groom file accepted. The biggest production grooms are a few hundred MB; anything larger is far
more likely to be the wrong file, and the parse holds a few copies of the point data in memory."""


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
