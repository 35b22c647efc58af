"""``python -m app.bench.highlights [--quick] [--label L] [--out DIR]``: low-roughness highlights across joints.

Issue 16's third point: at ``look.roughness = 0.05`` the highlights broke into white dashes. A container
segment is straight, so shading takes the guide's direction blended from one joint plane's normal to the
other's (glsl/shading/tangent.glsl). Blended by the segment's height, it met a tilted joint plane at
another weight on each side for every fiber off the axis, so the tangent stepped at joints, and the normal,
square to the straight fibers, kinked there; now the blend follows the planes and the normal turns with
it. This report measures that per scene (a strongly bent strand close up, sintel_hair.tfx's crown close up
and the whole groom; the close-up again without the self-shadow, which makes each fiber's brightness follow
its depth, so neighbouring fibers differ, and most of a joint's pixel pairs are neighbouring fibers: see
``joint_excess``) and per method (virtual, explicit):

  tangent step   numpy, per joint of the scene: the largest angle between the two segments' shading
                 tangents at points of the joint plane at the container's wall (24 around it), for the
                 height blend (``height_blended_axis``, the rule before) and the plane blend
                 (``joint_blended_axis``, the GLSL's twin); median, 90th percentile and largest, degrees.
                 For scale: the Marschner R lobe's width there, ``lobe_deg``.
  joint excess   from the pictures: over pairs of adjacent pixels that show one guide's container in two
                 segments, the share whose luminance step (mean of R, G, B, 8-bit levels) is larger by
                 more than ``JUMP_LEVELS`` than the larger step of the pixel pairs just before and after it,
                 each inside one of the two segments. A highlight's edge that happens to lie on a joint
                 steps as much on either side and does not count; a tangent that jumps does. Pairs may
                 show different fibers of the guide (sub-pixel fibers rarely fill two pixels): their
                 difference is noise common to the joint and its neighbours.

Before/after: run it once with ``--label before`` on the commit before the change (this file copied in)
and once with ``--label after``; each run keeps its pictures (``--pictures``, out/bench-highlights/
pictures_<label>.npz, not committed) and, once both exist, writes the contact sheet ``contact_sheet.png``
(before | after | the change x4, per scene and method) beside the CSV.
"""

from __future__ import annotations

import argparse
import csv
import platform
from datetime import date
from pathlib import Path

import numpy as np

from .timing import short_commit

JUMP_LEVELS = 8.0           # luminance levels (of 255) a joint's step may exceed its neighbours' by
WALL_POINTS = 24            # points around each joint plane's wall where the tangent step is measured
ROUGHNESS = 0.05
SCENES = ("bent strand", "sintel close-up", "sintel close-up, no self-shadow", "sintel_hair.tfx")
METHODS = ("virtual", "explicit")
LOOK = {"look.model": "marschner", "look.roughness": ROUGHNESS}
# one strand of 4 segments bent 120 degrees in all (40 per joint), fat for its segments, seen from the side
BENT = {"scene.generator": "single", "scene.radius": 0.35, "scene.length": 3.0, "scene.segments": 4,
        "scene.bend": 120.0, "fibers.rings": 6, "fibers.fiber_radius": 0.04, "camera.azimuth": 90.0,
        "camera.elevation": 10.0, "look.light_azimuth": 90.0, "look.light_elevation": 30.0}
# sintel's crown from 18 units (it frames itself at 56): fibers about 2 px wide at 960x540, so one fiber's
# pixels meet across a joint; the whole groom's fibers are a quarter of a pixel there
CLOSE = {"camera.distance": 18.0, "camera.target": (0.0, -3.0, 8.0)}


# --- the shading tangent in numpy ---------------------------------------------------------------------------
def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def joint_blended_axis(n0: np.ndarray, n1: np.ndarray, h: float, pl: np.ndarray) -> np.ndarray:
    """glsl/shading/tangent.glsl's twin: the guide's direction at local points ``pl`` (N, 3) of a segment
    (root at the origin, axis z, length ``h``; joint normals n0 into it and n1 out of it, local frame),
    blended by where each point lies between the two joint planes."""
    d0 = np.maximum(pl @ n0, 0.0)
    d1 = np.maximum((np.array([0.0, 0.0, h]) - pl) @ n1, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        u = np.where(d0 + d1 > 0, d0 / (d0 + d1), 0.5)[:, None]
    return _unit(n0 + (n1 - n0) * u)


def height_blended_axis(n0: np.ndarray, n1: np.ndarray, h: float, pl: np.ndarray) -> np.ndarray:
    """The rule before: the same blend by the height z / h (clamped), which a tilted joint plane does not
    follow off the axis."""
    u = np.clip(pl[:, 2:3] / h, 0.0, 1.0)
    return _unit(n0 + (n1 - n0) * u)


def turn_with(v: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """glsl/shading/tangent.glsl's twin: rows of ``v`` turned by the smallest rotation taking the unit rows
    of ``a`` to those of ``b`` (the shading normal turned from a fiber's direction to its tangent)."""
    k = np.cross(a, b)
    c = np.sum(a * b, -1, keepdims=True)
    return v * c + np.cross(k, v) + k * (np.sum(k * v, -1, keepdims=True) / np.maximum(1.0 + c, 1e-6))


def joint_tangent_steps(segments: np.ndarray, blend, points: int = WALL_POINTS) -> np.ndarray:
    """Per joint of the scene's rows (consecutive rows of one guide), the largest angle in degrees between
    the two segments' shading tangents ``blend`` gives at ``points`` points of the joint plane at the
    container's wall (radius r1 of the first segment)."""
    from .. import reference

    rows = np.asarray(segments, np.float64)
    joints = np.nonzero(rows[1:, 19] == rows[:-1, 19])[0]
    out = np.zeros(len(joints))
    ang = np.linspace(0.0, 2.0 * np.pi, points, endpoint=False)
    for k, i in enumerate(joints):
        a, b = reference.segment(rows[i]), reference.segment(rows[i + 1])
        fa, fb = np.stack([a.ex, a.ey, a.ez]), np.stack([b.ex, b.ey, b.ez])
        n = fa.T @ a.n1                                         # the joint plane's normal, world
        e1 = _unit(np.cross(n, fa[0] if abs(n @ fa[0]) < 0.9 else fa[1]))
        e2 = np.cross(n, e1)
        ring = rows[i, 7] * (np.cos(ang)[:, None] * e1 + np.sin(ang)[:, None] * e2)
        world = a.p0 + a.h * a.ez + ring                        # on the plane, at the wall
        ta = blend(a.n0, a.n1, a.h, (world - a.p0) @ fa.T) @ fa
        tb = blend(b.n0, b.n1, b.h, (world - b.p0) @ fb.T) @ fb
        out[k] = np.degrees(np.arccos(np.clip(np.sum(ta * tb, -1), -1.0, 1.0))).max()
    return out


def joint_bends(segments: np.ndarray) -> np.ndarray:
    """Per joint of the scene's rows, the angle between the two segments' axes in degrees (the tangent
    steps above are the blend's error at the wall, not the bend: sintel's height blend stepped 0.6 degrees
    at the median joint, which bends 9)."""
    rows = np.asarray(segments, np.float64)
    joints = np.nonzero(rows[1:, 19] == rows[:-1, 19])[0]
    axes = _unit(rows[:, 4:7] - rows[:, 0:3])
    return np.degrees(np.arccos(np.clip(np.sum(axes[joints] * axes[joints + 1], -1), -1.0, 1.0)))


def lobe_deg(roughness: float = ROUGHNESS) -> float:
    """The width (sigma) of glsl/shading/marschner.glsl's R lobe in degrees of tangent tilt: a Gaussian of
    beta sqrt 2 in sinL + sinV, where tilting the tangent by d moves sinL + sinV by about 2 d."""
    beta = max(roughness * roughness, 0.01)
    return float(np.degrees(beta * np.sqrt(2.0) / 2.0))


# --- the pictures' metric ------------------------------------------------------------------------------------
def joint_excess(color: np.ndarray, ids: np.ndarray, levels: float = JUMP_LEVELS,
                 same_fiber: bool | None = None) -> tuple[float, int]:
    """(percentage of joint pairs whose luminance step exceeds its in-segment neighbours' by more than
    ``levels``, number of joint pairs). A joint pair: two adjacent pixels (across or down) of the same
    guide in different segments; its neighbours: the pixel pairs continuing it on either side, each
    within the segment of the pixel it continues. Pairs with neither neighbour do not count.
    ``same_fiber``: True counts only the pairs whose two pixels show one fiber (ids' ring and fiber), False
    only those that show two, None all. Each fiber crosses a joint plane at its own height in the picture,
    so the boundary between two segments' pixels runs along fiber edges in steps: most joint pairs (81% on
    sintel's close-up) are two neighbouring fibers, compared with neighbours inside each fiber, and count
    how much fibers differ (the self-shadow makes each fiber's brightness follow its depth), not a joint;
    a plane through the middle of every segment measured 12.8% there against 16.2% at the joints. The
    pairs of one fiber say whether a fiber's shading runs on across its joint."""
    lum = np.asarray(color, np.float64)[..., :3].mean(-1)
    ids = np.asarray(ids, np.int64)
    guide = ids[..., 0]
    seg = ids[..., 3]
    fiber = (ids[..., 1] << 32) + ids[..., 2]
    excess = []
    for img_lum, img_guide, img_seg, img_fiber in ((lum, guide, seg, fiber), (lum.T, guide.T, seg.T, fiber.T)):
        # pairs (x, x + 1) along rows of one guide
        same = (img_guide[:, :-1] > 0) & (img_guide[:, :-1] == img_guide[:, 1:])
        inner = same & (img_seg[:, :-1] == img_seg[:, 1:])
        joint = same & (img_seg[:, :-1] != img_seg[:, 1:])
        if same_fiber is not None:
            joint &= (img_fiber[:, :-1] == img_fiber[:, 1:]) == same_fiber
        step = np.abs(np.diff(img_lum, axis=1))
        left = np.full(step.shape, np.nan)
        right = np.full(step.shape, np.nan)
        left[:, 1:] = np.where(inner[:, :-1], step[:, :-1], np.nan)      # pair (x - 1, x), x's segment
        right[:, :-1] = np.where(inner[:, 1:], step[:, 1:], np.nan)      # pair (x + 1, x + 2), x + 1's
        ctx = np.fmax(left, right)
        use = joint & np.isfinite(ctx)
        excess.append(step[use] - ctx[use])
    e = np.concatenate(excess)
    return (100.0 * float((e > levels).mean()) if len(e) else float("nan")), int(len(e))


# --- rendering ------------------------------------------------------------------------------------------------
def subject_params(name: str):
    from ..params import Params
    from ..presets import resolve_params
    from .grooms import HAIR_DATA

    if name == "bent strand":
        return Params({**BENT, **LOOK})
    p, _ = resolve_params(str(HAIR_DATA / "sintel_hair.tfx"), [])
    p = p.replace(**LOOK, **(CLOSE if name.startswith("sintel close-up") else {}))
    # with the self-shadow, fibers at different depths differ by tens of levels, and a joint's pairs of
    # neighbouring fibers count that (joint_excess): without it, what is left is the shading
    return p.replace(**{"look.self_shadow": "off"}) if name.endswith("no self-shadow") else p


OFFSETS = ((0.0, 0.0), (0.5, 0.0), (0.0, 0.5), (0.5, 0.5))     # sub-pixel shifts the metric is taken over


def render(ctx, programs, name: str, size, method: str, offsets=OFFSETS):
    """([color (H, W, 3) uint8, ...], [ids (H, W, 4) uint32, ...], scene) of one scene by one method, a
    frame per sub-pixel offset: on sub-pixel fibers two adjacent pixels often see different depths, and
    which pixels do moves with the offset, so one frame's figure is partly chance."""
    from ..render.camera import Camera
    from ..render.explicit import ExplicitRenderer
    from ..render.renderer import Renderer
    from ..scene.generators import build_scene

    p = subject_params(name)
    scene = build_scene(p)
    cam = Camera.from_params(p, scene, aspect=size[0] / size[1])
    r = Renderer(ctx, programs) if method == "virtual" else ExplicitRenderer(ctx, programs=programs)
    try:
        if method == "virtual":
            r.set_scene(scene)
        else:
            r.set_scene(scene, p)
        frames = [r.render(p, cam, size, outputs=("color", "ids"), offset=o) for o in offsets]
        return [f.color for f in frames], [f.ids for f in frames], scene
    finally:
        if method == "explicit":
            r.release()
        r.release_targets()


# the pictures the contact sheet shows and the part of each: (top, left, height, width), shares of it
CROPS = {"bent strand, virtual": (0.0, 0.25, 0.45, 0.35), "bent strand, explicit": (0.0, 0.25, 0.45, 0.35),
         "sintel close-up, virtual": (0.25, 0.05, 0.4, 0.4),
         "sintel close-up, no self-shadow, virtual": (0.25, 0.05, 0.4, 0.4),
         "sintel_hair.tfx, virtual": (0.3, 0.35, 0.25, 0.3)}


def contact_sheet(before: dict, after: dict, path: Path, zoom: int = 1) -> None:
    """A row per picture named in CROPS: before | after | the change x4 (a crop, enlarged ``zoom`` x)."""
    from PIL import Image, ImageDraw

    rows = []
    for key in after:
        if key not in before or key not in CROPS:
            continue
        a, b = before[key].astype(np.int32), after[key].astype(np.int32)
        h, w = a.shape[:2]
        top, left, ch, cw = CROPS[key]
        y0, x0, y1, x1 = int(top * h), int(left * w), int((top + ch) * h), int((left + cw) * w)
        change = np.clip(np.abs(a - b).max(-1, keepdims=True) * 4, 0, 255).repeat(3, -1)
        tiles = []
        for label, im in (("before", a), ("after", b), ("change x4", change)):
            t = Image.fromarray(im[y0:y1, x0:x1].astype(np.uint8))
            t = t.resize((t.width * zoom, t.height * zoom), Image.NEAREST)
            ImageDraw.Draw(t).text((4, 2), f"{key}: {label}", fill=(255, 255, 0))
            tiles += [np.asarray(t), np.full((t.height, 4, 3), 255, np.uint8)]
        rows.append(np.concatenate(tiles[:-1], 1))
    width = max(r.shape[1] for r in rows)
    rows = [np.pad(r, ((0, 4), (0, width - r.shape[1]), (0, 0)), constant_values=255) for r in rows]
    Image.fromarray(np.concatenate(rows, 0)).save(path)


COLUMNS = ["label", "scene", "method", "joint_pairs", "joint_excess_pct", "joint_excess_spread",
           "tangent_step_height_p50_deg", "tangent_step_height_p90_deg", "tangent_step_height_max_deg",
           "tangent_step_plane_max_deg", "lobe_deg", "joint_pairs_one_fiber", "joint_excess_one_fiber_pct",
           "bend_p50_deg", "bend_p90_deg"]


PICTURES = Path("out/bench-highlights")


def run(size=(960, 540), label: str = "after", out: Path | None = None, scenes=SCENES,
        command: str = "python -m app.bench.highlights", pictures_dir: Path = PICTURES) -> list[dict]:
    from ..gl.context import create_headless
    from ..gl.shaders import ProgramCache

    hc = create_headless()
    rows, pictures = [], {}
    try:
        programs = ProgramCache()
        for name in scenes:
            for method in METHODS:
                colors, ids, scene = render(hc.ctx, programs, name, size, method)
                each = [joint_excess(c, i) for c, i in zip(colors, ids)]
                pcts = [e[0] for e in each]
                pct, n = float(np.mean(pcts)), int(np.mean([e[1] for e in each]))
                one = [joint_excess(c, i, same_fiber=True) for c, i in zip(colors, ids)]
                bends = joint_bends(scene.segments)
                old = joint_tangent_steps(scene.segments, height_blended_axis)
                new = joint_tangent_steps(scene.segments, joint_blended_axis)
                rows.append({"label": label, "scene": name, "method": method, "joint_pairs": n,
                             "joint_excess_pct": pct, "joint_excess_spread": float(np.ptp(pcts)),
                             "tangent_step_height_p50_deg": float(np.median(old)),
                             "tangent_step_height_p90_deg": float(np.percentile(old, 90)),
                             "tangent_step_height_max_deg": float(old.max()),
                             "tangent_step_plane_max_deg": float(new.max()), "lobe_deg": lobe_deg(),
                             "joint_pairs_one_fiber": int(np.mean([e[1] for e in one])),
                             "joint_excess_one_fiber_pct": float(np.nanmean([e[0] for e in one]))
                             if any(e[1] for e in one) else float("nan"),
                             "bend_p50_deg": float(np.median(bends)), "bend_p90_deg": float(np.percentile(bends, 90))})
                pictures[f"{name}, {method}"] = colors[0]
                print(f"{label} {name} {method}: joint excess {pct:.2f}% (spread {np.ptp(pcts):.2f}) of {n} "
                      f"pairs; one fiber {rows[-1]['joint_excess_one_fiber_pct']:.2f}% of "
                      f"{rows[-1]['joint_pairs_one_fiber']}", flush=True)
    finally:
        hc.release()
    if out is not None:
        write_outputs(rows, pictures, out, label, size, command, hc.renderer, pictures_dir)
    return rows


def write_outputs(rows, pictures, out: Path, label: str, size, command: str, renderer: str,
                  pictures_dir: Path = PICTURES) -> None:
    out.mkdir(parents=True, exist_ok=True)
    pictures_dir.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(pictures_dir / f"pictures_{label}.npz", **pictures)
    path = out / "highlights.csv"
    kept = []
    if path.exists():                   # the other label's rows stay
        with open(path, newline="") as f:
            kept = [r for r in csv.DictReader(f) if r["label"] != label]
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, COLUMNS)
        w.writeheader()
        w.writerows(kept + [{k: r[k] for k in COLUMNS} for r in rows])
    with open(path, newline="") as f:
        table = list(csv.DictReader(f))
    def fmt(v: str | None) -> str:
        if v is None or v == "":            # a column newer than the other label's run
            return ""
        try:
            f = float(v)
        except ValueError:
            return v
        return str(int(f)) if f.is_integer() else f"{f:.3g}"

    lines = ["# Low-roughness highlights across joints (issue 16)", "",
             f"Last run: {date.today()}, commit {short_commit()}, label `{label}`, `{command}`. Machine: "
             f"{platform.processor() or platform.machine()}, {renderer}. Image {size[0]}x{size[1]}, "
             f"look.model = marschner, look.roughness = {ROUGHNESS}.", "",
             f"joint_excess_pct: share of one guide's pixel pairs across a joint whose luminance step exceeds "
             f"the in-segment steps beside it by more than {JUMP_LEVELS:g} levels, the mean over {len(OFFSETS)} "
             f"frames at sub-pixel offsets (spread: largest less smallest). tangent_step_*: per joint, the "
             f"largest angle between the two segments' shading tangents at the container's wall, by the height "
             f"blend (before) and the plane blend (after); lobe_deg: the R lobe's width. joint_*_one_fiber: the "
             f"joint pairs whose two pixels show one fiber (the rest are neighbouring fibers, whose difference "
             f"the staircase of fiber edges along a joint counts); bend_*: the joints' bends.", "",
             "| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
    lines += ["| " + " | ".join(fmt(r[k]) for k in COLUMNS) + " |" for r in table]
    if (pictures_dir / "pictures_before.npz").exists() and (pictures_dir / "pictures_after.npz").exists():
        before = dict(np.load(pictures_dir / "pictures_before.npz"))
        after = dict(np.load(pictures_dir / "pictures_after.npz"))
        contact_sheet(before, after, out / "contact_sheet.png")
        lines += ["", "![before | after | change x4, per scene and method](contact_sheet.png)"]
    elif (out / "contact_sheet.png").exists():     # this run's pictures match it where nothing was re-rendered
        lines += ["", "![before | after | change x4, per scene and method, from the last run that had both "
                  "labels' pictures](contact_sheet.png)"]
    (out / "README.md").write_text("\n".join(lines) + "\n")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m app.bench.highlights", description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="480x270")
    ap.add_argument("--label", default="after", help="this run's name in the CSV: before or after")
    ap.add_argument("--scene", action="append", choices=SCENES, help="repeatable (default: both)")
    ap.add_argument("--out", type=Path, default=Path("docs/bench/highlights"))
    ap.add_argument("--pictures", type=Path, default=PICTURES, help="where each label's pictures are kept")
    args = ap.parse_args(argv)
    size = (480, 270) if args.quick else (960, 540)
    command = "python -m app.bench.highlights" + (" " + " ".join(argv) if argv else "")
    run(size, args.label, args.out, args.scene or SCENES, command, args.pictures)
    print(f"wrote {args.out / 'README.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
