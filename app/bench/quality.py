"""``python -m app.bench.quality [--quick] [--out DIR]``: the speed-for-accuracy figures of the core.

Sections (each a Markdown table, a CSV and pictures in DIR):
  traversal  default preset at 640x360: ms per frame per mode, fiber tests per covered pixel next to the
             rings the ray crosses (the floor an ideal traversal cannot beat), brute / exact ratio
  shapes     straight, curled, twisted, combined fibers (and the other twist and curl patterns) x fast,
             exact at 640x360 and 1280x720, timed round-robin: ms per frame (wall and CPU) and tests per covered pixel
             beside their ratio to straight, pixels whose fiber differs from brute; the sliders' extremes
             (loop run-out, NaN, exact == brute)
  shape-grooms  the shapes section's curled, twisted and combined settings on the five shared grooms (their
             own segments), exact at 640x360: CPU ms per frame beside the same groom straight, tests per
             covered pixel, the fiber ranges the loop budget splits a frame into
  antialias  none, supersample 2 and 3, MSAA 2 and 4: ms per frame, and stability: pixels whose fiber
             id or colour changes when the camera moves a tenth of a pixel
  shadows    self-shadowing off, density estimate, traced shadow ray: cost and difference
  hash       the thesis's float LCG against the integer hash: how often a fiber's random numbers change
             between float32 and float64 evaluation, and under sub-pixel camera motion
Timing: warm-up, then the median of N frames of ``ctx.finish()`` plus a wall clock (llvmpipe frames can
pass the 32-bit GL timer's 4.29 s); the coefficient of variation is reported beside each median.
"""

from __future__ import annotations

import argparse
import csv
import platform
import time
from datetime import date
from pathlib import Path

import numpy as np
from PIL import Image
from tqdm import tqdm

from .. import reference          # the float64 judge; the model itself comes from app.fibers
from ..fibers import CH_LENGTH, CH_RADIAL, ring_layout, thesis_random
from ..gl.context import create_headless
from ..params import Params
from ..presets import find_preset
from ..render.camera import Camera
from ..render.debug_views import cost_image
from ..render.renderer import Renderer
from ..scene.generators import build_scene
from .timing import UNFILTERED, short_commit, time_frames, unfiltered


def frame_ms(ctx, fn, reps: int) -> tuple[float, float]:
    """(median ms, coefficient of variation) of ``fn`` followed by ctx.finish(), after two warm-up frames
    (timing.py: time_frames)."""
    t = time_frames(fn, warmup=2, reps=reps, sync=ctx.finish)
    return t.median_ms, t.cv


class Bench:
    def __init__(self, reps: int, gl=None):
        """``gl``: a HeadlessContext to render in (the tests' session context); default, a new one."""
        self.gl = gl or create_headless()
        self.ctx = self.gl.ctx
        self.renderer = Renderer(self.ctx)
        self.reps = reps

    def scene(self, p: Params):
        scene = build_scene(p)
        self.renderer.set_scene(scene)
        return scene, Camera.from_params(p, scene)

    def draw_ms(self, p, cam, size, mode=None):
        """Time the frame as the viewer sees it: draw plus finish, no read-back."""
        return frame_ms(self.ctx, lambda: self.renderer.render(p, cam, size, outputs=("draw",), mode=mode), self.reps)


def traversal_section(b: Bench, size, out: Path, bar) -> list[dict]:
    p = unfiltered(find_preset("default").params)      # the unfiltered traversal (timing.UNFILTERED)
    scene, cam = b.scene(p)
    rows = []
    images = []
    for mode in ("fast", "exact", "brute"):
        reps = b.reps if mode != "brute" else max(1, b.reps // 5)
        b.reps, saved = reps, b.reps
        ms, cv = b.draw_ms(p, cam, size, mode)
        b.reps = saved
        cost = b.renderer.render(p, cam, size, outputs=("cost",), mode=mode).cost
        covered = cost[..., 2] > 0
        rows.append({"mode": mode, "ms": ms, "cv": cv, "fps": 1000 / ms,
                     "tests_per_px": float(cost[..., 0][covered].mean()),
                     "arcs_per_px": float(cost[..., 1][covered].mean()),
                     "max_loop_iters": float(cost[..., 3].max())})
        images.append(cost_image(cost, vmax=60.0 if mode != "brute" else None))
        bar.update()
    # the floor: rings crossed by the covered rays (float64, on a subsample)
    w, h = size
    ro, rd = cam.rays(w, h)
    covered = (b.renderer.render(p, cam, size, outputs=("cost",), mode="exact").cost[..., 2] > 0).reshape(-1)
    idx = np.nonzero(covered)[0][:: max(1, covered.sum() // 4000)]
    crossed = reference.rings_crossed(scene, p, ro[idx], rd[idx], cam.near).mean()
    for r in rows:
        r["rings_crossed"] = float(crossed)
    exact = next(r for r in rows if r["mode"] == "exact")
    brute = next(r for r in rows if r["mode"] == "brute")
    exact["brute_over_exact"] = brute["tests_per_px"] / exact["tests_per_px"]
    Image.fromarray(np.concatenate(images, 1)).save(out / "traversal_cost.png")
    Image.fromarray(b.renderer.render(p, cam, size).color).save(out / "traversal_default.png")
    return rows


SHAPES = {
    "straight": {},
    "curled": {"shape.curl_amplitude": 0.35, "shape.curl_frequency": 6.0},
    "twisted": {"shape.twist": 1.0},
    "combined": {"shape.curl_amplitude": 0.3, "shape.twist": 0.8, "shape.twist_pattern": "alternating",
                 "shape.ellipsoid": 0.6, "scene.segments": 4},
}
# the other twist and curl patterns and the ellipsoid, measured at the first size only
PATTERNS = {
    "twist ramped": {"shape.twist": 1.0, "shape.twist_pattern": "ramped"},
    "twist alternating": {"shape.twist": 1.0, "shape.twist_pattern": "alternating"},
    "curl wave": {"shape.curl_amplitude": 0.35, "shape.curl_frequency": 6.0, "shape.curl_pattern": "wave"},
    "ellipsoid": {"shape.ellipsoid": 0.8, "scene.segments": 4},
}
# the ends of the sliders: checked (loop run-out, NaN, exact == brute) on a smaller image, not compared
EXTREMES = {
    "twist +8 uniform": {"shape.twist": 8.0},
    "twist -8 ramped": {"shape.twist": -8.0, "shape.twist_pattern": "ramped"},
    "twist +8 alternating": {"shape.twist": 8.0, "shape.twist_pattern": "alternating"},
    "curl 0.5 x 64 helix": {"shape.curl_amplitude": 0.5, "shape.curl_frequency": 64.0},
    "curl 0.5 x 64 wave": {"shape.curl_amplitude": 0.5, "shape.curl_frequency": 64.0, "shape.curl_pattern": "wave"},
    "ellipsoid 1": {"shape.ellipsoid": 1.0, "scene.segments": 4},
    "all at once": {"shape.twist": -8.0, "shape.twist_pattern": "ramped", "shape.curl_amplitude": 0.5,
                    "shape.curl_frequency": 64.0, "shape.ellipsoid": 1.0, "scene.segments": 4},
}
SHAPE_SIZES = ((640, 360), (1280, 720))


def shapes_section(b: Bench, size, out: Path, bar) -> list[dict]:
    """Curved fibers against straight ones, timed round-robin in one process (a frame of each shape in
    turn, so load on the machine falls on all of them alike): ms per frame and fiber tests per covered
    pixel, each beside its ratio to straight fibers at the same size and mode; the loop budget canary,
    NaN, and the pixels whose fiber differs from brute force (rendered once per shape and size)."""
    sizes = SHAPE_SIZES if size == (640, 360) else (size, (2 * size[0], 2 * size[1]))
    rows, sheet, costs = [], [], []
    for k, sz in enumerate(sizes):
        shapes = {**SHAPES, **(PATTERNS if k == 0 else {})}
        runs = {}
        for name, values in shapes.items():
            p = Params({"scene.count": 8, **values, **UNFILTERED})
            scene = build_scene(p)
            r = Renderer(b.ctx, b.renderer.programs)
            r.set_scene(scene)
            runs[name] = (p, r, Camera.from_params(p, scene))
        for mode in ("fast", "exact"):
            timing = _round_robin(b, runs, sz, mode)
            for name, (p, r, cam) in runs.items():
                f = r.render(p, cam, sz, outputs=("ids", "cost", "iters", "geom"), mode=mode)
                covered = f.cost[..., 2] > 0
                rows.append({"size": f"{sz[0]}x{sz[1]}", "shape": name, "mode": mode,
                             "ms": timing[name][0], "cv": timing[name][1], "cpu_ms": timing[name][2],
                             "tests_per_px": float(f.cost[..., 0][covered].mean()),
                             "max_loop_iters": float(f.iters.max()),
                             "nan": bool(not np.isfinite(f.geom).all()), "_ids": f.ids, "_hit": f.hit})
                if mode == "exact" and k == 0:
                    sheet.append(r.render(p, cam, sz).color)
                    costs.append(cost_image(f.cost, vmax=60.0))
        for name, (p, r, cam) in runs.items():
            brute = r.render(p, cam, sz, outputs=("ids",), mode="brute")
            for row in rows:
                if row["shape"] == name and row["size"] == f"{sz[0]}x{sz[1]}" and "_ids" in row:
                    hit = row.pop("_hit") | brute.hit
                    differ = np.any(row.pop("_ids")[..., :3] != brute.ids[..., :3], -1) & hit
                    row["differ_from_brute_pct"] = 100.0 * differ.sum() / max(1, hit.sum())
            r.release_targets()
            bar.update()
    for row in rows:
        base = next(x for x in rows if x["shape"] == "straight" and x["size"] == row["size"]
                    and x["mode"] == row["mode"])
        row["ms_vs_straight"] = row["ms"] / base["ms"]
        row["cpu_vs_straight"] = row["cpu_ms"] / base["cpu_ms"]
        row["tests_vs_straight"] = row["tests_per_px"] / base["tests_per_px"]
        row["loop_run_out"] = row["max_loop_iters"] >= 65_535
    rows += _shape_extremes(b, (size[0] // 2, size[1] // 2))
    bar.update()
    _save_sheet(sheet, out / "shapes.png")
    _save_sheet(costs, out / "shapes_cost.png")
    order = ["size", "shape", "mode", "ms", "cv", "ms_vs_straight", "cpu_ms", "cpu_vs_straight", "tests_per_px",
             "tests_vs_straight", "differ_from_brute_pct", "max_loop_iters", "loop_run_out", "nan"]
    return [{k: r[k] for k in order if k in r} for r in rows]


def _round_robin(b: Bench, runs: dict, size, mode: str) -> dict:
    """(median ms, cv, median CPU ms) per run: two warm-up frames each, then b.reps rounds of one frame of
    every run. The CPU time (time.process_time, which counts llvmpipe's rendering threads) is what to read
    on a machine others share: the wall clock there counts their work too."""
    samples = {name: [] for name in runs}
    cpu = {name: [] for name in runs}
    for rep in range(-2, b.reps):
        for name, (p, r, cam) in runs.items():
            c0 = time.process_time()
            t = time_frames(lambda: r.render(p, cam, size, outputs=("draw",), mode=mode), warmup=0, reps=1,
                            sync=b.ctx.finish)
            if rep >= 0:
                samples[name] += t.samples_ms
                cpu[name].append(1e3 * (time.process_time() - c0))
    return {name: (float(np.median(s)), float(np.std(s) / np.mean(s)), float(np.median(cpu[name])))
            for name, s in samples.items()}


def _shape_extremes(b: Bench, size) -> list[dict]:
    """The sliders' ends: exact and brute once each, one container seen at a slant (every ray climbs)."""
    rows = []
    for name, values in EXTREMES.items():
        p = Params({"scene.count": 3, **values, **UNFILTERED})
        scene = build_scene(p)
        r = Renderer(b.ctx, b.renderer.programs)
        r.set_scene(scene)
        cam = Camera.from_params(p.replace(**{"camera.elevation": 35.0}), scene)
        exact = r.render(p, cam, size, outputs=("ids", "cost", "iters", "geom"), mode="exact")
        brute = r.render(p, cam, size, outputs=("ids", "iters"), mode="brute")
        hit = exact.hit | brute.hit
        differ = np.any(exact.ids[..., :3] != brute.ids[..., :3], -1) & hit
        covered = exact.cost[..., 2] > 0
        it = max(float(exact.iters.max()), float(brute.iters.max()))   # the most one draw ran (MAX blend)
        rows.append({"size": f"{size[0]}x{size[1]}", "shape": f"extreme: {name}", "mode": "exact",
                     "tests_per_px": float(exact.cost[..., 0][covered].mean()),
                     "differ_from_brute_pct": 100.0 * differ.sum() / max(1, hit.sum()),
                     "max_loop_iters": it, "loop_run_out": it >= 65_535,
                     "nan": bool(not np.isfinite(exact.geom).all())})
        r.release_targets()
    return rows


def shape_grooms_section(b: Bench, size, out: Path, bar) -> list[dict]:
    """The shapes section's settings on the five shared grooms, as a groom opens (resolve_params), each
    groom with its own segments: CPU ms per frame, exact mode, round-robin per groom, beside the same
    groom's straight frame; fiber tests per covered pixel, the visibility strategy and the fiber ranges
    the loop budget splits a frame into (renderer.py: draw_ranges; each range is a pass of its own).
    Brute force is not run here (the shapes section holds exact == brute)."""
    from ..presets import resolve_params
    from ..render.renderer import draw_ranges, traversals_per_fragment
    from .grooms import GROOM_FILES, HAIR_DATA

    rows = []
    for groom in GROOM_FILES:
        path = HAIR_DATA / groom
        if not path.exists():
            print(f"shape-grooms: {path} not found, skipped (expects ../shared/hair-data beside the checkout)")
            bar.update()
            continue
        base, _ = resolve_params(str(path), [])
        scene = build_scene(base)
        runs = {}
        for name, values in SHAPES.items():
            p = base.replace(**{k: v for k, v in values.items() if k != "scene.segments"}, **UNFILTERED)
            r = Renderer(b.ctx, b.renderer.programs)
            r.set_scene(scene)
            runs[name] = (p, r, Camera.from_params(p, scene, aspect=size[0] / size[1]))
        timing = _round_robin(b, runs, size, "exact")
        mine = []
        for name, (p, r, cam) in runs.items():
            f = r.render(p, cam, size, outputs=("cost",), mode="exact")
            covered = f.cost[..., 2] > 0
            visibility = r.visibility(p, cam, size, "exact")
            walks = 2 if visibility == "walk" else 0            # as the renderer's passes count them
            mine.append({"groom": groom, "shape": name, "segments": len(scene.segments),
                         "cpu_ms": timing[name][2], "tests_per_px": float(f.cost[..., 0][covered].mean()),
                         "visibility": visibility,
                         "ranges": len(draw_ranges(p, scene, "exact", traversals_per_fragment(p, "exact"), walks))})
            r.release_targets()
        straight = mine[0]                                      # SHAPES begins with straight
        for row in mine:
            row["cpu_vs_straight"] = row["cpu_ms"] / straight["cpu_ms"]
            row["tests_vs_straight"] = row["tests_per_px"] / straight["tests_per_px"]
        rows += mine
        bar.update()
    order = ["groom", "segments", "shape", "cpu_ms", "cpu_vs_straight", "tests_per_px", "tests_vs_straight",
             "visibility", "ranges"]
    return [{k: r[k] for k in order} for r in rows]


def _save_sheet(images: list, path: Path, per_row: int = 4) -> None:
    """Images side by side, ``per_row`` to a row (blank tiles pad the last one)."""
    if not images:
        return
    blank = np.zeros_like(images[0])
    rows = [images[i:i + per_row] for i in range(0, len(images), per_row)]
    rows = [np.concatenate(r + [blank] * (per_row - len(r)), 1) for r in rows]
    Image.fromarray(np.concatenate(rows, 0)).save(path)


AA = {"none": {}, "supersample 2": {"quality.supersample": 2}, "supersample 3": {"quality.supersample": 3},
      "msaa 2": {"quality.msaa": 2}, "msaa 4": {"quality.msaa": 4}}


def antialias_section(b: Bench, size, out: Path, bar) -> list[dict]:
    """Thin fibers: move the camera a tenth of a pixel and count what changes."""
    # the antialias options of the unfiltered frame (the filter's own bench: antialias.py)
    base = {"scene.count": 12, "fibers.fiber_radius": 0.004, "fibers.phi_step": 1.0, **UNFILTERED}
    rows = []
    crops = []
    for name, values in AA.items():
        p = Params({**base, **values})
        scene, cam = b.scene(p)
        if values.get("quality.msaa", 0) > b.ctx.max_samples:
            continue
        ms, cv = frame_ms(b.ctx, lambda: b.renderer.render(p, cam, size, outputs=("color",)), b.reps)
        a = b.renderer.render(p, cam, size, outputs=("color", "ids"))
        moved = b.renderer.render(p, cam, size, outputs=("color", "ids"), offset=(0.1, 0.0))
        shown = a.hit | moved.hit
        color_changed = (np.abs(a.color.astype(int) - moved.color.astype(int)).max(-1) > 8) & shown
        id_changed = np.any(a.ids[..., :3] != moved.ids[..., :3], -1) & shown
        rows.append({"antialias": name, "ms": ms, "cv": cv,
                     "colour_changed_pct": 100.0 * color_changed.sum() / max(1, shown.sum()),
                     "id_changed_pct": 100.0 * id_changed.sum() / max(1, shown.sum())})
        h, w = a.color.shape[:2]
        crops.append(a.color[h // 3: h // 3 + h // 3, w // 3: w // 3 + w // 4])
        bar.update()
    big = [np.asarray(Image.fromarray(c).resize((c.shape[1] * 3, c.shape[0] * 3), Image.NEAREST)) for c in crops]
    Image.fromarray(np.concatenate(big, 1)).save(out / "antialias.png")
    return rows


def hash_section(b: Bench, size, out: Path, bar) -> list[dict]:
    p = find_preset("default").params
    lay = ring_layout(p)
    ring = np.repeat(np.arange(lay.rings), lay.n)
    j = np.arange(lay.fibers_per_container) - np.repeat(lay.first, lay.n)
    slot = np.degrees(lay.rot[ring] + j * lay.dphi[ring])
    rows = []
    for channel, what in ((CH_RADIAL, "radial jitter"), (CH_LENGTH, "length")):
        r32 = thesis_random(slot, ring, channel, np.float32)
        r64 = thesis_random(slot, ring, channel, np.float64)
        rows.append({"hash": "thesis fract(1207.523 phi)", "number": what,
                     "differs_gt_1e-3_pct": 100.0 * (np.abs(r32 - r64) > 1e-3).mean(),
                     "differs_gt_1e-6_pct": 100.0 * (np.abs(r32 - r64) > 1e-6).mean()})
        rows.append({"hash": "integer (lowbias32)", "number": what, "differs_gt_1e-3_pct": 0.0,
                     "differs_gt_1e-6_pct": 0.0})
    # Both hashes are evaluated from integers and uniforms per (ring, fiber) in the shader, so neither
    # changes from frame to frame; the thesis's flips are between implementations and precisions.
    bar.update(2)
    return rows


def shadows_section(b: Bench, size, out: Path, bar) -> list[dict]:
    """Self-shadowing: what the density estimate and the traced shadow ray cost, and how far apart
    their pictures are (mean absolute difference of the shaded fibers, 8-bit)."""
    p0 = unfiltered(find_preset("default").params)     # the unfiltered traversal (timing.UNFILTERED)
    rows, images = [], {}
    for mode in ("off", "density", "traced"):
        p = p0.replace(**{"look.self_shadow": mode})
        scene, cam = b.scene(p)
        ms, cv = b.draw_ms(p, cam, size)
        f = b.renderer.render(p, cam, size, outputs=("color", "cost", "ids"))
        covered = f.cost[..., 2] > 0
        images[mode] = f
        rows.append({"self_shadow": mode, "ms": ms, "cv": cv,
                     "tests_per_px": float(f.cost[..., 0][covered].mean())})
        bar.update()
    hit = images["traced"].hit
    for r in rows:
        diff = np.abs(images[r["self_shadow"]].color.astype(int) - images["traced"].color.astype(int))
        r["mean_abs_diff_to_traced"] = float(diff[hit].mean())
    Image.fromarray(np.concatenate([images[m].color for m in ("off", "density", "traced")], 1)).save(
        out / "shadows.png")
    return rows


SECTIONS = {"traversal": traversal_section, "shapes": shapes_section, "shape-grooms": shape_grooms_section,
            "antialias": antialias_section, "shadows": shadows_section, "hash": hash_section}


def write_table(rows: list[dict], path: Path) -> str:
    if not rows:
        return ""
    keys = list(dict.fromkeys(k for r in rows for k in r))
    with open(path.with_suffix(".csv"), "w", newline="") as f:
        w = csv.DictWriter(f, keys)
        w.writeheader()
        w.writerows(rows)
    fmt = lambda v: f"{v:.3g}" if isinstance(v, float) else str(v)  # noqa: E731
    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    lines += ["| " + " | ".join(fmt(r.get(k, "")) for k in keys) + " |" for r in rows]
    return "\n".join(lines)


def section_markdown(name: str, table: str, out: Path, header: str) -> None:
    """A section's table under the header of the run that made it, kept in DIR/NAME.md so a run of some
    sections leaves the others' figures in the README (with their own date and commit)."""
    (out / f"{name}.md").write_text(f"## {name}\n\n{header}\n\n{table}\n")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m app.bench.quality", description=__doc__.split("\n")[0])
    ap.add_argument("sections", nargs="*", choices=[[], *SECTIONS], help="default: all")
    ap.add_argument("--quick", action="store_true", help="smaller images and fewer frames")
    ap.add_argument("--out", type=Path, default=Path("docs/bench/quality"))
    args = ap.parse_args(argv)
    names = args.sections or list(SECTIONS)
    args.out.mkdir(parents=True, exist_ok=True)
    b = Bench(reps=3 if args.quick else 10)
    size = (320, 180) if args.quick else (640, 360)
    steps = {"traversal": 3, "shapes": 13, "shape-grooms": 5, "antialias": 5, "shadows": 3, "hash": 2}
    command = " ".join(["python -m app.bench.quality", *args.sections] + (["--quick"] if args.quick else []))
    header = (f"Date {date.today()}, commit {short_commit()}, `{command}`. "
              f"Machine: {platform.processor() or platform.machine()}, {b.gl.renderer}, {b.gl.version}. "
              f"Image {size[0]}x{size[1]}; medians of {b.reps} frames after 2 warm-up frames "
              f"(ctx.finish() + wall clock).")
    with tqdm(total=sum(steps[n] for n in names), desc="bench quality", unit="run") as bar:
        for name in names:
            rows = SECTIONS[name](b, size, args.out, bar)
            section_markdown(name, write_table(rows, args.out / name), args.out, header)
    md = ["# Speed for accuracy: the core's figures\n"]
    md += [(args.out / f"{n}.md").read_text() for n in SECTIONS if (args.out / f"{n}.md").exists()]
    (args.out / "README.md").write_text("\n".join(md))
    print(f"wrote {args.out / 'README.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
