"""Orientation: which axis of a groom file is up, and the rotation that makes it +Z.

The renderer is Z-up, so every groom is rotated on load so that the file's up axis becomes +Z; ``up="auto"``
guesses that axis from the strands themselves (see :func:`guess_up`).
"""

from __future__ import annotations

import numpy as np

UP_CHOICES = ("auto", "x", "-x", "y", "-y", "z", "-z")
"""Values of ``up``: the axis *of the file* that points up (it becomes +Z). ``"-x"`` means the file's -X is
up, i.e. gravity along +X. The parameter table offers a subset; all six signed axes work here."""

# Formats whose authoring tools fix the orientation: TressFX assets come from Y-up game/DCC pipelines and the
# USC-HairSalon database is Y-up by construction. .hair and .ply carry no such convention.
_FORMAT_UP = {"tfx": "y", "data": "y"}

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
