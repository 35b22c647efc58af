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

    def strand_end_colors(self) -> np.ndarray | None:
        """Linear RGB at every strand's root and tip, (n_strands, 2, 3) float64, or None when the file stores
        no colour array (a .hair header's default colour is not used: cyHair writes white there).

        The file's values are taken as display colours (sRGB-encoded in [0, 1], as a painter picks them and
        as 8-bit PLY colours are) and decoded to the linear values the shader mixes. Only the root and tip are
        kept, per strand; the scene holds them per guide (:func:`guide_colors`), never per fiber."""
        if self.colors is None:
            return None
        ends = np.stack([np.stack([c[0], c[-1]]) for c in self.colors]) if self.colors else np.zeros((0, 2, 3))
        return srgb_to_linear(np.clip(np.nan_to_num(ends, nan=0.0), 0.0, 1.0))

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



def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """The sRGB transfer function inverted (IEC 61966-2-1), for colours in [0, 1]."""
    c = np.asarray(c, np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def guide_colors(groom: Groom, labels: np.ndarray, n_guides: int) -> np.ndarray | None:
    """Root and tip colour of each guide, (n_guides, 2, 3) float32: the mean over the strands it stands for
    (``labels``: guide index of every groom strand, -1 where dropped). None without file colours."""
    ends = groom.strand_end_colors()
    if ends is None:
        return None
    labels = np.asarray(labels, np.int64)
    use = labels >= 0
    count = np.bincount(labels[use], minlength=n_guides)[:n_guides].astype(np.float64)
    out = np.zeros((n_guides, 2, 3))
    for e in range(2):
        for ch in range(3):
            out[:, e, ch] = np.bincount(labels[use], weights=ends[use, e, ch], minlength=n_guides)[:n_guides]
    out /= np.maximum(count, 1.0)[:, None, None]
    return out.astype(np.float32)


def colour_summary(guide_colors: np.ndarray | None, source: str) -> str:
    """One line for ``vfiber info``: whether the file's colours reach the scene, what they are like and what
    they cost (``source``: the look.color_source in effect)."""
    if guide_colors is None:
        return "none in the file: every strand takes the look's colour"
    n = len(guide_colors)
    along = float(np.abs(guide_colors[:, 1] - guide_colors[:, 0]).max()) if n else 0.0
    mean = guide_colors.reshape(-1, 3).mean(axis=0) if n else np.zeros(3)
    spread = guide_colors.reshape(-1, 3).std(axis=0).mean() if n else 0.0
    kind = "the same at root and tip" if along < 1e-3 else f"changing root to tip (by up to {along:.2f})"
    use = ("in use (look.color_source = file)" if source == "file"
           else "not used: look.color_source = look (set it to file to see them)")
    shown = ", ".join(f"{c:.3f}" for c in mean)
    return (f"root and tip per guide, {kind}; mean linear ({shown}), spread {spread:.2f}; {n * 32:,} B on the GPU; "
            f"{use}")
