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

One module per concern, in the order the data flows:

* :mod:`.formats` -- the four readers (bytes -> raw points and counts), each checking its header;
* :mod:`.orient` -- which file axis is up and the rotation onto +Z;
* :mod:`.load` -- reading a file safely, then parse, skip, orient and scale: a :class:`Groom`;
* :mod:`.guides` -- per-strand guides or k-means clusters of strands, resampled, with their radii;
* :mod:`.segments` -- how many segments the guides get (:func:`auto_segments`);
* :mod:`.build` -- the groom's scene: guides -> containers through ``Scene.from_polylines``.
"""

from __future__ import annotations

from ..containers import container_rows
from .build import groom_scene, scene_from_groom
from .formats import _EXTENSIONS as _EXTENSIONS  # re-exported: the suffix list callers read
from .formats import FORMATS, GROOM_SUFFIXES
from .groom import Groom, GroomError
from .guides import Guides, default_radius, resample, resample_many, strands_to_guides
from .load import MAX_FILE_BYTES, load_groom, parse_groom
from .orient import UP_CHOICES, guess_up, up_rotation
from .segments import MAX_TURN_DEG, SEGMENT_TOLERANCE, auto_segments, chord_errors, joint_turns

__all__ = [
    "FORMATS", "GROOM_SUFFIXES", "MAX_FILE_BYTES", "SEGMENT_TOLERANCE", "UP_CHOICES", "Groom", "GroomError", "Guides",
    "MAX_TURN_DEG", "auto_segments", "chord_errors", "container_rows", "default_radius", "groom_scene",
    "guess_up", "joint_turns", "load_groom",
    "parse_groom", "resample", "resample_many", "scene_from_groom", "strands_to_guides", "up_rotation",
]
