"""What every part of groom loading shares: the loaded :class:`Groom` and the :class:`GroomError` that
names a file and what is wrong with it."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...errors import VfiberError


class GroomError(VfiberError, ValueError):
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

