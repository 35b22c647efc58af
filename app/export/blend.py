"""Export a scene as a self-contained .blend that Cycles renders as it is: ``vfiber export-blend``.

What the file holds (docs/osl.md, "A Blender scene"):

* **A few mesh objects**, ``vfiber_containers`` and ``vfiber_containers.nbK``, at the scene origin (no
  rotation or scale): a closed mitred octagonal prism around every container segment (container_boxes),
  grouped by how many neighbour slots its faces carry (K, NEIGHBOUR_SLOTS). Each face carries its segment
  as **face-domain attributes**: ``vf_p0``, ``vf_p1`` (end points, object space), ``vf_n0``, ``vf_n1`` (joint planes),
  ``vf_fx`` (frame x), ``vf_rrg`` (r0, r1, guide), ``vf_v`` (v0, v1, 0): the GL's per-instance rows
  (app/scene/containers.py), so bent multi-segment guides, taper and joint planes come through unchanged.
  A groom file with colours adds ``vf_root_color`` and ``vf_tip_color``: the linear colour of the face's
  guide at its root and tip (``Scene.guide_colors``), which the shader uses when look.color_source = file.
  And the rows of its **neighbours** (neighbour_lists: the segments whose containers reach into its prism),
  ``vf_nb{k}_p0`` .. ``vf_nb{k}_v`` for k < K, with which the shader lets a camera ray stop only at the
  container holding the nearest fiber (docs/osl.md, "Overlapping containers").
* **The look's material**: a Script node in *Internal* mode whose text (``vfiber.osl``) is the shader of
  :mod:`app.export.osl`, embedded in the file, compiled by this exporter (the bytecode is saved with the
  node). Cycles exports a mesh attribute only when a non-script node asks for it, so one Attribute node
  per name feeds an AOV Output (``vf_keep``, one value pass) through a chain of Vector Math adds.
* **Camera, lights, background** of ``vfiber render TARGET --size WxH``: the same orbit camera and
  resolution; a Sun lamp per light of ``look.light_rig`` (key, fill, rim); a world that shows
  ``look.background`` to camera rays and lights the fibers with the preview's ambient fill plus the
  environment image (packed into the file, turned by a Mapping node).
* **Render settings the shader needs**: Cycles on the CPU with OSL, transparent bounces for every prism a
  ray can cross, transparent film, Standard view transform, output to ``//render_####.png`` (relative).

No absolute path of the writing machine and no add-on: ``blender -b scene.blend -f 1`` renders it.

API
===

``export_blend(params, path, size=(640, 360), name="scene", progress=print) -> BlendStats``
    Build the scene from ``params`` (a preset's or a groom's) and write the .blend atomically. Imports bpy
    (the ``[blender]`` extra) into this process and resets its scene.
``container_boxes(segments) -> (vertices, faces, face_sizes, face_rows)``
    The proxy mesh as numpy arrays (no bpy): 16 vertices and 10 faces per segment.
``neighbour_lists(segments, cap) -> (lists, counts)``
    Per segment the other segments whose containers reach into its prism, deepest overlap first.
``main(argv) -> int``
    ``vfiber export-blend TARGET -o scene.blend [--size WxH] [--set KEY=VALUE ...]``.
``export_blend_in_child(params, path, size) -> str``
    The same in a child process (the viewer: bpy stays out of the GL process); returns its report line,
    raises RuntimeError with its one-line error.
"""

from __future__ import annotations

import argparse
import hashlib
import math
import os
import re
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from collections.abc import Callable, Sequence

import numpy as np

from app.params import Params
from app.scene.containers import joint_slope

__all__ = ["BlendStats", "ATTRIBUTES", "container_boxes", "export_blend", "main", "make_parser", "neighbour_lists"]

#: face attributes of the proxy mesh: name -> columns of the segment row (app/scene/containers.py)
ATTRIBUTES: dict[str, tuple[int, int, int] | tuple[int, int, None]] = {
    "vf_p0": (0, 1, 2), "vf_p1": (4, 5, 6), "vf_n0": (8, 9, 10), "vf_n1": (12, 13, 14),
    "vf_fx": (16, 17, 18), "vf_rrg": (3, 7, 19), "vf_v": (11, 15, None),
}
#: face attributes of the proxy mesh when the groom file has colours: the linear colour of the face's guide at
#: its root and tip (Scene.guide_colors), read by the shader when look.color_source = "file"
COLOR_ATTRIBUTES = ("vf_root_color", "vf_tip_color")
OBJECT_NAME = "vfiber_containers"
TEXT_NAME = "vfiber.osl"
#: Blender's largest transparent bounce count; each box a ray passes costs two (in and out)
TRANSPARENT_BOUNCES = 1024
#: the box circumscribes the round container with this relative margin (the shader intersects the round one)
BOX_MARGIN = 1e-3

#: sides of the prism around each container: 8 reaches 8 % past the round container (a box: 41 %), so
#: neighbouring containers' proxies overlap little more than the containers do
PRISM_SIDES = 8


@dataclass
class BlendStats:
    path: Path
    segments: int
    guides: int
    vertices: int
    faces: int
    seconds: float
    bytes: int
    size: tuple[int, int]
    neighbour_cap: int = 0      # neighbour slots a prism may carry in this scene (neighbour_cap)
    neighbour_rows: int = 0     # neighbour slots written, over all prisms
    objects: int = 1            # mesh objects: one per slot count


def container_boxes(segments: np.ndarray, sides: int = PRISM_SIDES) -> tuple[np.ndarray, list, np.ndarray]:
    """(vertices (2 sides N, 3) float32, faces (flat vertex indices), face_sizes, face_rows: the segment of
    each face) of the proxy mesh: per segment a prism of ``sides`` sides circumscribing its round container.

    Each prism ends on its segment's joint planes (mitred), so the prisms of one guide meet at its joints
    instead of overlapping: a ray meets a bent guide's containers in the order it crosses them, and the first
    container with a fiber on the ray holds the nearest fiber. A joint so steep that a mitred prism would
    fold (short segment, sharp turn) gets the bounding slab of glsl/geometry/container.glsl instead."""
    s = np.asarray(segments, np.float64)
    p0, p1 = s[:, 0:3], s[:, 4:7]
    axis = p1 - p0
    h = np.linalg.norm(axis, axis=1)
    ez = axis / h[:, None]
    fx = s[:, 16:19]
    ex = fx - ez * (fx * ez).sum(1, keepdims=True)
    ex /= np.linalg.norm(ex, axis=1)[:, None]
    ey = np.cross(ez, ex)
    r = np.maximum(s[:, 3], s[:, 7])
    pad = BOX_MARGIN * r
    half = r * (1.0 + BOX_MARGIN) / math.cos(math.pi / sides)     # the prism's corners, circumscribing
    n0 = np.stack([(s[:, 8:11] * e).sum(1) for e in (ex, ey, ez)], 1)
    n1 = np.stack([(s[:, 12:15] * e).sum(1) for e in (ex, ey, ez)], 1)
    z_lo_slab = -r * joint_slope(n0[:, 2]) - pad
    z_hi_slab = h + r * joint_slope(n1[:, 2]) + pad
    ang = 2.0 * math.pi * np.arange(sides) / sides
    cx, cy = np.cos(ang), np.sin(ang)
    z_lo = -(n0[:, 0:1] * cx + n0[:, 1:2] * cy) * half[:, None] / np.maximum(n0[:, 2:3], 1e-6) - pad[:, None]
    z_hi = h[:, None] - (n1[:, 0:1] * cx + n1[:, 1:2] * cy) * half[:, None] / np.maximum(n1[:, 2:3], 1e-6) \
        + pad[:, None]
    folded = ((z_hi - z_lo).min(1) < 0.05 * h) | (n0[:, 2] < 0.2) | (n1[:, 2] < 0.2)
    z_lo = np.where(folded[:, None], z_lo_slab[:, None], z_lo)
    z_hi = np.where(folded[:, None], z_hi_slab[:, None], z_hi)
    rim = ex[:, None] * (half[:, None] * cx)[..., None] + ey[:, None] * (half[:, None] * cy)[..., None]
    bottom = p0[:, None] + rim + ez[:, None] * z_lo[..., None]
    top = p0[:, None] + rim + ez[:, None] * z_hi[..., None]
    verts = np.concatenate([bottom, top], 1).reshape(-1, 3).astype(np.float32)
    n = len(s)
    k = np.arange(sides)
    quads = np.stack([k, (k + 1) % sides, sides + (k + 1) % sides, sides + k], 1)      # outward: ccw from outside
    local = np.concatenate([quads.ravel(), k[::-1], sides + k])
    sizes1 = np.array([4] * sides + [sides, sides], np.int32)
    faces = (local[None] + 2 * sides * np.arange(n)[:, None]).ravel().astype(np.int32)
    sizes = np.tile(sizes1, n)
    rows = np.repeat(np.arange(n), sides + 2)
    return verts, faces, sizes, rows


#: every face also carries its segment's *neighbours*: the rows of the other segments whose containers
#: reach into its prism, in slots vf_nb{k}_p0 .. vf_nb{k}_v (the seven ATTRIBUTES each, k = 0, 1, ...).
#: At a prism's entry face the shader shows its own nearest fiber only when no neighbour has a fiber
#: nearer on the ray; otherwise the ray passes on to the nearer fiber's own prism (docs/osl.md,
#: "Overlapping containers"). Prisms are grouped into objects by how many slots they need
#: (NEIGHBOUR_SLOTS), so the attribute memory follows the neighbour counts rather than the largest one.
NEIGHBOUR_SLOTS = (0, 2, 4, 8, 12, 16, 24, 32, 48, 64)
#: neighbour rows (prisms x slots) a scene may carry at most: each costs ~5.4 KB of render memory (7 vectors
#: on 10 faces in Blender, 28 triangles in Cycles; measured on Ratboy_mohawk), so this adds at most ~3.6 GiB.
#: A denser scene keeps every prism's deepest-overlapping neighbours under a lower per-scene cap
#: (neighbour_cap): harolongo (158,100 segments, 114 neighbours each on average) gets 4
NEIGHBOUR_ROW_BUDGET = 700_000
#: relative slack of every bounding volume of the traversal (glsl/common/epsilon.glsl EPS_BOUND)
EPS_BOUND = 1e-4


def neighbour_attribute(k: int, name: str) -> str:
    """The face attribute of neighbour slot ``k`` holding what ``name`` (an ATTRIBUTES key) holds for the
    face's own segment: vf_p0 -> vf_nb3_p0."""
    return f"vf_nb{k}_{name.removeprefix('vf_')}"


def overlap_capsules(segments: np.ndarray, sides: int = PRISM_SIDES):
    """Capsules (axis ends a, b and radius) around each segment's prism and around its container: the prism
    (circumscribed octagon, mitred or slab ends, container_boxes) lies within radius ``half`` of its axis
    extended by half * tan(joint tilt) + pad at each end; the container within its bounding cylinder
    (r_bound (1 + EPS_BOUND)) between the planes of its bounding slab (r_bound tan(tilt) past each end)."""
    s = np.asarray(segments, np.float64)
    p0, p1 = s[:, 0:3], s[:, 4:7]
    ez = (p1 - p0) / np.linalg.norm(p1 - p0, axis=1)[:, None]
    r = np.maximum(s[:, 3], s[:, 7])
    slope0 = joint_slope((s[:, 8:11] * ez).sum(1))
    slope1 = joint_slope((s[:, 12:15] * ez).sum(1))
    half = r * (1.0 + BOX_MARGIN) / math.cos(math.pi / sides)
    pad = BOX_MARGIN * r
    prism = (p0 - ez * (half * slope0 + pad)[:, None], p1 + ez * (half * slope1 + pad)[:, None], half)
    rc = r * (1.0 + EPS_BOUND)
    container = (p0 - ez * (rc * slope0)[:, None], p1 + ez * (rc * slope1)[:, None], rc)
    return prism, container


def segment_distance(a1: np.ndarray, b1: np.ndarray, a2: np.ndarray, b2: np.ndarray) -> np.ndarray:
    """Distance between the line segments a1-b1 and a2-b2, row by row (closest points clamped to both)."""
    d1, d2, w = b1 - a1, b2 - a2, a1 - a2
    a, e = (d1 * d1).sum(1), (d2 * d2).sum(1)
    b, c, f = (d1 * d2).sum(1), (d1 * w).sum(1), (d2 * w).sum(1)
    den = a * e - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(den > 1e-12 * a * e, np.clip((b * f - c * e) / den, 0.0, 1.0), 0.0)
        t = (b * s + f) / e
        s = np.where(t < 0.0, np.clip(-c / a, 0.0, 1.0), np.where(t > 1.0, np.clip((b - c) / a, 0.0, 1.0), s))
    t = np.clip(t, 0.0, 1.0)
    q = a1 + d1 * s[:, None] - a2 - d2 * t[:, None]
    return np.sqrt((q * q).sum(1))


def _axis_cells(a: np.ndarray, b: np.ndarray, spacing: float, base: np.ndarray, cell: float,
                strides: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(segment, cell key) of points sampled along each axis a-b at most ``spacing`` apart, ends included;
    one row per distinct (segment, cell); key = cell index . strides."""
    length = np.linalg.norm(b - a, axis=1)
    count = np.ceil(length / spacing).astype(np.int64) + 1
    seg = np.repeat(np.arange(len(a)), count)
    k = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    f = k / np.maximum(count[seg] - 1, 1)
    pts = a[seg] + (b - a)[seg] * f[:, None]
    keys = np.floor((pts - base) / cell).astype(np.int64) @ strides
    return _distinct(seg, keys)


def _distinct(seg: np.ndarray, keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct (seg, key) pairs (keys >= 0), sorted by segment."""
    span = int(keys.max()) + 1
    both = np.unique(seg * span + keys)
    return both // span, both % span


def neighbour_lists(segments: np.ndarray, cap: int = NEIGHBOUR_SLOTS[-1]) -> tuple[np.ndarray, np.ndarray]:
    """(lists (n, cap) int64, -1 padded; counts (n,)): for each segment Z the segments Y whose container
    capsule overlaps Z's prism capsule (overlap_capsules; a conservative test of the container reaching into
    the prism), deepest overlap (radii sum minus axis distance) first, at most ``cap``; ``counts`` before the
    cap. The next and previous segment of the same guide are left out: their containers end on the joint
    plane that the prism overshoots by only BOX_MARGIN r (they meet the prism in that sliver alone).

    Candidates come from a grid: both axes are sampled at most ``spacing`` apart, so two capsules that
    overlap (axes within reach, the largest radii sum) have samples within reach + spacing, one cell, of each
    other: in the same or adjacent cells; the prism's cells are widened by one cell each way and joined
    with the containers' cells."""
    s = np.asarray(segments, np.float64)
    n = len(s)
    (ap, bp, rp), (ac, bc, rc) = overlap_capsules(s)
    empty = np.full((n, cap), -1, np.int64)
    if n < 2:
        return empty, np.zeros(n, np.int64)
    reach = float(rp.max() + rc.max())
    spacing = 0.25 * reach      # finer samples, smaller cells: fewer candidate pairs per true one
    cell = reach + spacing
    # a margin of one cell each way, so a neighbouring cell's key never wraps to another row of the grid
    ends = np.concatenate([ap, bp, ac, bc])
    base = ends.min(0) - cell
    dims = np.floor((ends.max(0) - base) / cell).astype(np.int64) + 2
    strides = np.array([dims[1] * dims[2], dims[2], 1], np.int64)
    zs, zk = _axis_cells(ap, bp, spacing, base, cell, strides)
    ys, yk = _axis_cells(ac, bc, spacing, base, cell, strides)
    order = np.argsort(yk, kind="stable")
    y_keys, y_segs = yk[order], ys[order]
    guide = s[:, 19]
    found_i, found_j, found_depth = [], [], []
    offsets = np.stack(np.meshgrid([-1, 0, 1], [-1, 0, 1], [-1, 0, 1], indexing="ij"), -1).reshape(-1, 3) @ strides
    chunk = 4096
    bounds = np.searchsorted(zs, np.arange(0, n + chunk, chunk))     # zs is sorted by segment
    for c0, c1 in zip(bounds[:-1], bounds[1:]):
        fat_seg, fk = _distinct(np.repeat(zs[c0:c1], len(offsets)), (zk[c0:c1, None] + offsets[None]).ravel())
        lo, hi = np.searchsorted(y_keys, fk, "left"), np.searchsorted(y_keys, fk, "right")
        m = hi - lo
        i = np.repeat(fat_seg, m)
        j = y_segs[np.repeat(lo, m) + np.arange(m.sum()) - np.repeat(np.cumsum(m) - m, m)]
        pair = np.unique(i * n + j)
        i, j = pair // n, pair % n
        keep = (i != j) & ~((guide[i] == guide[j]) & (np.abs(i - j) == 1))
        i, j = i[keep], j[keep]
        depth = rp[i] + rc[j] - segment_distance(ap[i], bp[i], ac[j], bc[j])
        hit = depth >= 0.0
        found_i.append(i[hit]), found_j.append(j[hit]), found_depth.append(depth[hit])
    i, j, depth = np.concatenate(found_i), np.concatenate(found_j), np.concatenate(found_depth)
    order = np.lexsort((-depth, i))
    i, j = i[order], j[order]
    counts = np.bincount(i, minlength=n)
    rank = np.arange(len(i)) - np.repeat(np.cumsum(counts) - counts, counts)
    take = rank < cap
    empty[i[take], rank[take]] = j[take]
    return empty, counts


def neighbour_cap(counts: np.ndarray, budget: int = NEIGHBOUR_ROW_BUDGET) -> int:
    """The largest slot count of NEIGHBOUR_SLOTS whose bucketed neighbour rows fit in ``budget``."""
    best = 0
    for cap in NEIGHBOUR_SLOTS:
        if slot_bucket(np.minimum(counts, cap)).sum() <= budget:
            best = cap
    return best


def slot_bucket(counts: np.ndarray) -> np.ndarray:
    """The slot count (one of NEIGHBOUR_SLOTS) of the object a prism with ``counts`` neighbours goes to."""
    slots = np.asarray(NEIGHBOUR_SLOTS)
    return slots[np.searchsorted(slots, np.minimum(counts, slots[-1]), "left")]


def _face_attribute(segments: np.ndarray, rows: np.ndarray, cols) -> np.ndarray:
    out = np.zeros((len(rows), 3), np.float32)
    for j, c in enumerate(cols):
        if c is not None:
            out[:, j] = segments[rows, c]
    return out


def color_face_attributes(segments: np.ndarray, rows: np.ndarray, guide_colors: np.ndarray) -> dict[str, np.ndarray]:
    """{COLOR_ATTRIBUTES name: (faces, 3) float32}: each face's guide's root and tip colour."""
    guide = segments[rows, 19].astype(np.int64)
    return {name: np.ascontiguousarray(guide_colors[guide, end], np.float32)
            for end, name in enumerate(COLOR_ATTRIBUTES)}


# ------------------------------------------------------------------------------------------------------ bpy


def neighbour_face_attributes(segments: np.ndarray, rows: np.ndarray, lists: np.ndarray, slots: int):
    """(neighbour_attribute(k, name), (faces, 3) float32) for k < ``slots``, one at a time (harolongo's are
    ~20 MB each): the rows of each face's neighbours (``lists``, neighbour_lists; zeros where a slot is
    empty, which the shader reads as the list's end)."""
    for k in range(slots):
        j = lists[rows, k] if k < lists.shape[1] else np.full(len(rows), -1)
        filled = j >= 0
        for name, cols in ATTRIBUTES.items():
            values = np.zeros((len(rows), 3), np.float32)
            values[filled] = _face_attribute(segments, j[filled], cols)
            yield neighbour_attribute(k, name), values


def _build_mesh(bpy, segments: np.ndarray, guide_colors: np.ndarray | None, subset: np.ndarray,
                lists: np.ndarray, slots: int, name: str):
    """The prisms of the segments ``subset`` as one mesh, with their own rows and ``slots`` neighbour slots."""
    verts, faces, sizes, local_rows = container_boxes(segments[subset])
    rows = subset[local_rows]
    mesh = bpy.data.meshes.new(name)
    mesh.vertices.add(len(verts))
    mesh.vertices.foreach_set("co", verts.ravel())
    mesh.loops.add(faces.size)
    mesh.loops.foreach_set("vertex_index", faces)
    mesh.polygons.add(len(sizes))
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int32)
    mesh.polygons.foreach_set("loop_start", starts)
    mesh.update(calc_edges=True)
    def attributes():
        for attr_name, cols in ATTRIBUTES.items():
            yield attr_name, _face_attribute(segments, rows, cols)
        if guide_colors is not None:
            yield from color_face_attributes(segments, rows, guide_colors).items()
        yield from neighbour_face_attributes(segments, rows, lists, slots)

    for attr_name, values in attributes():
        a = mesh.attributes.new(attr_name, "FLOAT_VECTOR", "FACE")
        a.data.foreach_set("vector", values.ravel())
    mesh.update()
    return mesh, len(verts), len(sizes)


def portable_bytecode(oso: str) -> str:
    """The compiled shader without the paths of the machine that compiled it. oslc writes its command line
    (a temporary output file, Blender's include folder) in a comment, and the source file's path in every
    ``%filename`` hint and source-line comment, which only error messages and debuggers read. A farm must not
    see where the file was made: each path becomes its file name (Blender's temporary copy of the text
    becomes the text's own name)."""
    def name(path: str) -> str:
        base = path.replace("\\", "/").rsplit("/", 1)[-1]
        return TEXT_NAME if re.fullmatch(r"tmp\w*\.osl", base) else base

    out = []
    for line in oso.split("\n"):
        if line.startswith("# options:"):
            line = "# options: (left out by vfiber: paths of the exporting machine)"
        elif line.startswith("#"):
            line = re.sub(r"(?:[A-Za-z]:)?[\w./\\-]*[/\\][\w.-]+", lambda m: name(m.group(0)), line)
        out.append(line)
    return re.sub(r'%filename\{"([^"]*)"\}', lambda m: '%filename{"' + name(m.group(1)) + '"}', "\n".join(out))


def _material(bpy, scene, source: str, name: str, attributes=tuple(ATTRIBUTES)):
    from . import blender as B

    text = bpy.data.texts.new(TEXT_NAME)
    text.from_string(source)
    mat = bpy.data.materials.new(f"vfiber {name}")
    nt = mat.node_tree
    for n in list(nt.nodes):
        if n.bl_idname != "ShaderNodeOutputMaterial":
            nt.nodes.remove(n)
    out = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    out.target = "CYCLES"
    out.location = (400, 0)
    script = nt.nodes.new("ShaderNodeScript")
    script.name = script.label = "vfiber"
    script.mode = "INTERNAL"
    script.script = text
    reports: list[str] = []
    import cycles.osl as cycles_osl
    with B._capture_fds(reports):
        ok = cycles_osl.update_script_node(script, lambda kind, msg: reports.append(f"{kind}: {msg}"))
    if not ok or not script.outputs:
        raise B.BlenderRenderError(f"Blender could not compile the vfiber shader: {' '.join(reports)[-2000:]}")
    script.bytecode = portable_bytecode(script.bytecode)
    script.bytecode_hash = hashlib.md5(script.bytecode.encode(), usedforsecurity=False).hexdigest()
    nt.links.new(script.outputs["BSDF"], out.inputs["Surface"])
    # Cycles exports a mesh attribute only when a non-script node asks for it: one Attribute node per name,
    # summed into one AOV value (a sink that keeps them alive without touching the image)
    total = None
    for i, attr_name in enumerate(attributes):
        at = nt.nodes.new("ShaderNodeAttribute")
        at.attribute_type, at.attribute_name = "GEOMETRY", attr_name
        at.location = (-400, -200 - 120 * i)
        if total is None:
            total = at.outputs["Vector"]
            continue
        add = nt.nodes.new("ShaderNodeVectorMath")
        add.operation = "ADD"
        add.location = (-150, -200 - 120 * i)
        nt.links.new(total, add.inputs[0])
        nt.links.new(at.outputs["Vector"], add.inputs[1])
        total = add.outputs["Vector"]
    aov = nt.nodes.new("ShaderNodeOutputAOV")
    aov.aov_name = "vf_keep"
    aov.location = (150, -400)
    nt.links.new(total, aov.inputs["Color"])
    layer_aov = scene.view_layers[0].aovs.add()
    layer_aov.name, layer_aov.type = "vf_keep", "COLOR"
    return mat, script


#: the preview's Lambert-like term is albedo * 0.8 * intensity at normal incidence; Cycles' diffuse gives
#: albedo * strength / pi: a preview light of intensity I is a Sun of strength 0.8 pi I, and an environment
#: piece (radiance x solid angle, app/render/environment.py) scales the same, so the world's image does too
SUN_PER_INTENSITY = 0.8 * math.pi


def _suns(bpy, rig: dict) -> list:
    """One Sun lamp per light of ``look.light_rig`` (key, fill, rim), shining from its direction."""
    from mathutils import Vector

    out = []
    for light in rig["lights"]:
        color = [float(c) for c in light["color"]]
        peak = max(color)
        name = f"vfiber {light['kind']} light"
        sun = bpy.data.lights.new(name, "SUN")
        sun.energy = SUN_PER_INTENSITY * peak
        sun.color = [c / peak for c in color] if peak > 0 else [1.0, 1.0, 1.0]
        sun.angle = 0.0
        ob = bpy.data.objects.new(name, sun)
        # a sun shines along its -Z, so its +Z points toward the light
        ob.rotation_euler = Vector(light["direction"]).to_track_quat("Z", "Y").to_euler()
        out.append(ob)
    return out


def _environment_image(bpy, env: dict):
    """The environment's lat-long image, packed into the file under a relative name (no path of this
    machine is saved)."""
    from . import blender as B

    try:
        image = bpy.data.images.load(env["image"], check_existing=False)
        image.pack()
    except RuntimeError as e:
        raise B.BlenderRenderError(f"{env['image']}: Blender could not load the environment image ({e})") from None
    name = Path(env["image"]).name
    image.name = name
    # packed: the data is in the file, these are only its name (the packed copy keeps the source's path too)
    image.filepath_raw = f"//{name}"
    for packed in image.packed_files:
        packed.filepath = f"//{name}"
    return image


def _world(bpy, p: Params, rig: dict):
    """Camera rays see ``look.background``; every other ray sees what lights the preview's fibers: the
    ambient fill plus the environment image (its median-cut lights there), added as the preview adds them."""
    world = bpy.data.worlds.new("vfiber world")
    nt = world.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    out = nt.nodes.new("ShaderNodeOutputWorld")
    seen = nt.nodes.new("ShaderNodeBackground")
    seen.name = seen.label = "vfiber background"
    seen.inputs["Color"].default_value = (*p["look.background"], 1.0)
    fill = nt.nodes.new("ShaderNodeBackground")
    fill.name = fill.label = "vfiber fill"
    # the preview's ambient fill: ambient * albedo * (0.55 + 0.45 max(N.z, 0)), about 0.78 ambient on average
    a = 0.775 * p["look.ambient"]
    fill.inputs["Color"].default_value = (a, a, a, 1.0)
    lighting = fill.outputs["Background"]
    env = rig["environment"]
    if env is not None and env["strength"] > 0:
        coords = nt.nodes.new("ShaderNodeTexCoord")
        mapping = nt.nodes.new("ShaderNodeMapping")
        mapping.name = mapping.label = "vfiber environment rotation"
        # TEXTURE: the image turns by +rotation about +Z (the lookup turns the other way)
        mapping.vector_type = "TEXTURE"
        mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(env["rotation_degrees"]))
        tex = nt.nodes.new("ShaderNodeTexEnvironment")
        tex.name = tex.label = "vfiber environment"
        tex.projection = "EQUIRECTANGULAR"
        tex.image = _environment_image(bpy, env)
        tex.image.colorspace_settings.name = "Linear Rec.709"
        light = nt.nodes.new("ShaderNodeBackground")
        light.name = light.label = "vfiber environment light"
        light.inputs["Strength"].default_value = SUN_PER_INTENSITY * env["strength"]
        add = nt.nodes.new("ShaderNodeAddShader")
        nt.links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
        nt.links.new(mapping.outputs["Vector"], tex.inputs["Vector"])
        nt.links.new(tex.outputs["Color"], light.inputs["Color"])
        nt.links.new(fill.outputs["Background"], add.inputs[0])
        nt.links.new(light.outputs["Background"], add.inputs[1])
        lighting = add.outputs["Shader"]
    path = nt.nodes.new("ShaderNodeLightPath")
    mix = nt.nodes.new("ShaderNodeMixShader")
    nt.links.new(path.outputs["Is Camera Ray"], mix.inputs["Fac"])
    nt.links.new(lighting, mix.inputs[1])
    nt.links.new(seen.outputs["Background"], mix.inputs[2])
    nt.links.new(mix.outputs["Shader"], out.inputs["Surface"])
    return world


def _render_settings(scene, p: Params, size: tuple[int, int]) -> None:
    scene.render.engine = "CYCLES"
    cy = scene.cycles
    cy.device = "CPU"
    cy.shading_system = True
    cy.samples = 64
    cy.use_adaptive_sampling = True
    cy.use_denoising = False
    cy.max_bounces = 8
    cy.transparent_max_bounces = TRANSPARENT_BOUNCES
    render = scene.render
    render.film_transparent = True
    render.resolution_x, render.resolution_y = size
    render.resolution_percentage = 100
    render.pixel_aspect_x = render.pixel_aspect_y = 1.0
    render.filepath = "//render_"
    render.image_settings.file_format = "PNG"
    render.image_settings.color_mode = "RGBA"
    scene.frame_start = scene.frame_end = scene.frame_current = 1
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = p["look.exposure"]


def export_blend(params: Params, path: str | Path, size: tuple[int, int] = (640, 360), name: str = "scene",
                 progress: Callable[[str], None] | None = print) -> BlendStats:
    """Write the .blend for ``params`` (see the module docstring). Atomic: a failure keeps an old file."""
    from app.atomic import atomic_path
    from app.render.camera import Camera
    from app.render.look import light_rig
    from app.scene.generators import build_scene

    from . import blender as B
    from .osl import osl_source

    path = Path(path)
    say = progress or (lambda msg: None)
    t0 = time.perf_counter()
    bpy, _ = B._bpy()
    say(f"building the scene of {name} ...")
    scene_data = build_scene(params)
    if scene_data.n_segments == 0:
        raise ValueError(f"{name}: the scene has no containers to export")
    cam = Camera.from_params(params, scene_data)  # what `vfiber render` uses, whatever the size
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.name = "vfiber"
    _render_settings(scene, params, size)   # the engine first: the script node asks it for its sockets
    say(f"{scene_data.n_segments} container segments of {scene_data.n_guides} guides -> prisms ...")
    colors = scene_data.guide_colors
    segments = scene_data.segments
    lists, counts = neighbour_lists(segments)
    cap = neighbour_cap(counts)
    slots = slot_bucket(np.minimum(counts, cap))
    say(f"neighbours per prism: mean {counts.mean():.1f}, max {counts.max()}; {cap} slots at most "
        f"({int(np.maximum(counts - cap, 0).sum())} of {int(counts.sum())} left out) ...")
    used = sorted({int(k) for k in slots})
    say("compiling the shader ...")
    attributes = tuple(ATTRIBUTES) + (COLOR_ATTRIBUTES if colors is not None else ()) + tuple(
        neighbour_attribute(k, a) for k in range(max(used)) for a in ATTRIBUTES)
    mat, _script = _material(bpy, scene, osl_source(params, name), name, attributes)
    n_verts = n_faces = 0
    for k in used:
        subset = np.flatnonzero(slots == k)
        # one object per slot count: the attribute memory follows each prism's own neighbour count
        ob_name = OBJECT_NAME if k == used[0] else f"{OBJECT_NAME}.nb{k}"
        mesh, nv, nf = _build_mesh(bpy, segments, colors, subset, lists, k, ob_name)
        n_verts, n_faces = n_verts + nv, n_faces + nf
        mesh.materials.append(mat)
        ob = bpy.data.objects.new(ob_name, mesh)
        ob.location = tuple(float(v) for v in scene_data.origin)
        scene.collection.objects.link(ob)
    cam_ob = B._camera_object(bpy, dict(position=cam.position.tolist(), target=cam.target.tolist(),
                                        up=cam.up.tolist(), fov_deg=cam.fov, near=cam.near, far=cam.far))
    cam_ob.name = "vfiber camera"
    scene.collection.objects.link(cam_ob)
    scene.camera = cam_ob
    with tempfile.TemporaryDirectory(prefix="vfiber-light-") as light_folder:
        rig = light_rig(params, light_folder)     # a generated map is written there, then packed
        for sun_ob in _suns(bpy, rig):
            scene.collection.objects.link(sun_ob)
        scene.world = _world(bpy, params, rig)
    say(f"writing {path} ...")
    with atomic_path(path) as tmp:
        # a temporary name ending in .blend: Blender appends .blend otherwise
        tmp_blend = Path(str(tmp) + ".blend")
        noise: list[str] = []   # Blender prints "Info: Saved copy as ..." with the temporary name
        try:
            with B._capture_fds(noise):
                bpy.ops.wm.save_as_mainfile(filepath=str(tmp_blend), compress=True, relative_remap=True,
                                            copy=True, check_existing=False)
            os.replace(tmp_blend, tmp)
        finally:
            if tmp_blend.exists():
                tmp_blend.unlink()
    seconds = time.perf_counter() - t0
    return BlendStats(path, scene_data.n_segments, scene_data.n_guides, n_verts, n_faces, seconds,
                      path.stat().st_size, tuple(size), cap, int(slots.sum()), len(used))


def export_blend_in_child(params: Params, path: str | Path, size: tuple[int, int] = (640, 360)) -> str:
    import json
    import subprocess
    import tempfile

    with tempfile.TemporaryDirectory(prefix="vfiber-blend-") as d:
        pj = Path(d) / "params.json"
        pj.write_text(json.dumps(params.values))
        code = "import sys; from app.cli import main; sys.exit(main(sys.argv[1:]))"
        proc = subprocess.run([sys.executable, "-c", code, "export-blend", "--params-json", str(pj), "-o", str(path),
                               "--size", f"{size[0]}x{size[1]}"], capture_output=True, text=True)
    if proc.returncode != 0:
        lines = [ln for ln in proc.stderr.splitlines() if ln.startswith("vfiber:")] or proc.stderr.splitlines()[-1:]
        raise RuntimeError(lines[-1].removeprefix("vfiber: ") if lines else f"exit status {proc.returncode}")
    return next((ln for ln in reversed(proc.stdout.splitlines()) if ln.startswith("wrote ")), proc.stdout.strip())


# ------------------------------------------------------------------------------------------ command line


def make_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="vfiber export-blend",
        description="Write a .blend that Blender Cycles renders as it is: every container of the scene on one "
                    "mesh, the look's OSL shader embedded, the camera, lights (key, fill, rim, environment) "
                    "and background of the preview. "
                    "See docs/osl.md.")
    ap.add_argument("target", metavar="TARGET", nargs="?",
                    help="preset name or .toml file, or a groom file (.hair .data .tfx .ply)")
    ap.add_argument("--params-json", metavar="FILE", help=argparse.SUPPRESS)  # the viewer's current parameters
    ap.add_argument("-o", dest="output", metavar="OUT.blend", help="output file (default: TARGET.blend)")
    ap.add_argument("--size", default="640x360",
                    help="render resolution WIDTHxHEIGHT (default 640x360, as vfiber render)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="override a parameter, e.g. --set fibers.rings=20 (repeatable)")
    ap.add_argument("--preset", dest="look", metavar="LOOK", help="a preset's look on a groom TARGET (its "
                    "fibers, shape, look and light; the groom keeps its scene and camera; docs/presets.md)")
    return ap


def main(argv: Sequence[str] | None = None) -> int:
    from app.errors import UsageError
    from app.presets import resolve_params
    from app.units import parse_size

    from . import blender as B

    args = make_parser().parse_args(list(sys.argv[1:] if argv is None else argv))
    size = parse_size(args.size)
    if args.params_json:
        import json

        params, name = Params(json.loads(Path(args.params_json).read_text())), Path(args.output or "scene").stem
    elif args.target:
        params, _label = resolve_params(args.target, args.set, look=args.look)
        name = Path(args.target).stem if Path(args.target).suffix else args.target
    elif args.look:
        params, _label = resolve_params(None, args.set, look=args.look)
        name = Path(args.look).stem if Path(args.look).suffix else args.look
    else:
        raise UsageError("export-blend needs a TARGET: a preset name or file, or a groom file")
    out = Path(args.output or f"{name}.blend")
    if out.suffix.lower() != ".blend":
        raise UsageError(f"-o {out}: a Blender scene file ends in .blend")
    folder = out.parent if str(out.parent) else Path(".")
    if not folder.is_dir():
        raise UsageError(f"{out}: folder {folder} does not exist")
    try:
        B._bpy()
    except B.BlenderUnavailable:
        raise UsageError("export-blend needs Blender's Python module: pip install 'vfiber[blender]' "
                         "(bpy==5.0.1, Python 3.11)") from None
    stats = export_blend(params, out, size, name, progress=lambda msg: print(msg, file=sys.stderr))
    print(f"wrote {out} ({stats.bytes / 1e6:.1f} MB): {stats.segments} container segments of {stats.guides} "
          f"guides on {stats.objects} mesh object(s), {stats.neighbour_rows} neighbour rows (at most "
          f"{stats.neighbour_cap} per prism), {size[0]}x{size[1]}, {stats.seconds:.1f} s; render it with "
          f"blender -b {out.name} -f 1")
    return 0
