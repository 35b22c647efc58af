"""Curly_100 with interpolated children: how many, how blended, and the alternatives measured against them
(docs/grooms.md, "Curly: interpolated children"): ``python docs/bench/looks-children/run.py
docs/bench/looks-children``.

One process, 640x360, the looks suite's judge (the interpolated reference built from looks.REFERENCE_SETS,
its camera) and the file's strands alone. Every variant is rendered at five placement seeds
(``scene.seed`` 1-5: the children's spiral turns), because on Curly the orientation figure is a median over
7-13% of the covered pixels and moves by 1-3 degrees with the seed alone. Variants:

* ``fibers.groom_auto=true`` with ``scene.groom_children`` 0, 3, 8, 12, 15 (the automatic count), 20;
* the blend: 1 guide per child (a translated copy of the nearest strand: the "translated placement" of the
  fiber model, done with containers) and 2, against the product's 4;
* 16 segments instead of the automatic 8 (the fold rule then picks 19 children);
* the alternative the issue named, (b): no children, each container's radius clamped at every joint to c x
  the local radius of curvature (segment length / turn angle), c = 0.5 and 0.8. Not in the product: the
  rows are changed here, after the build.

Each orientation figure is also split into the compared pixels inside the mass (``INSIDE_PX`` within the
reference's silhouette) and those at its rim. Writes rows.json (one row per variant and seed) and
summary.md (per variant: median and range over seeds),
and sheet.png (strands | reference | plain | auto without children | auto with children). About five minutes
on the 2-core llvmpipe machine.
"""
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[3]))
from app.bench import looks, strand_reference  # noqa: E402
from app.bench.grooms import HAIR_DATA  # noqa: E402
from app.contact_sheet import compose_sheet  # noqa: E402
from app.gl.context import create_headless  # noqa: E402
from app.presets import resolve_params  # noqa: E402
from app.render.camera import Camera  # noqa: E402
from app.render.explicit import ExplicitRenderer  # noqa: E402
from app.render.renderer import Renderer  # noqa: E402
from app.scene.containers import Scene  # noqa: E402
from app.scene.generators import build_scene  # noqa: E402
from app.scene.grooms import children  # noqa: E402

SIZE = (640, 360)
SEEDS = (1, 2, 3, 4, 5)
GROOM = "Curly_100.ply"
AUTO = ["fibers.groom_auto=true"]
VARIANTS = {
    "plain (groom_auto off)": (looks.REFERENCE_SETS, {}),
    **{f"auto, {n} children": (AUTO + [f"scene.groom_children={n}"], {}) for n in (0, 3, 8, 12)},
    "auto (15 children, the automatic count)": (AUTO, {}),
    "auto, 20 children": (AUTO + ["scene.groom_children=20"], {}),
    "auto, 16 segments (19 children: the fold rule follows the segments)": (AUTO + ["scene.segments=16"], {}),
    "auto, children blend 1 guide (translated copies)": (AUTO, {"k": 1}),
    "auto, children blend 2 guides": (AUTO, {"k": 2}),
    "(b) auto, no children, radius <= 0.5 x local curl radius": (AUTO + ["scene.groom_children=0"], {"clamp": 0.5}),
    "(b) auto, no children, radius <= 0.8 x local curl radius": (AUTO + ["scene.groom_children=0"], {"clamp": 0.8}),
}


INSIDE_PX = 12       # "inside": at least this far within the reference's silhouette (blurred coverage)


def inside(mask: np.ndarray, px: int = INSIDE_PX) -> np.ndarray:
    """The pixels of ``mask`` whose 4-neighbourhood stays in it ``px`` steps deep (an erosion)."""
    m = looks.blurred_coverage(mask).copy()
    for _ in range(px):
        e = m.copy()
        e[1:] &= m[:-1]
        e[:-1] &= m[1:]
        e[:, 1:] &= m[:, :-1]
        e[:, :-1] &= m[:, 1:]
        m = e
    return m


def split(ref, frame, deep: np.ndarray) -> tuple[float, float, float]:
    """Median angle difference (the suite's orientation figure) over the compared pixels inside the mass
    and at its rim, and the share of the compared pixels that are inside."""
    da, ca = looks.orientation_field(looks.luminance(ref.color))
    db, cb = looks.orientation_field(looks.luminance(frame.color))
    use = (ref.ids[..., 0] > 0) & (frame.ids[..., 0] > 0) & (ca >= looks.COHERENCE_MIN) & (cb >= looks.COHERENCE_MIN)
    d = looks.angle_difference_deg(da, db)
    med = lambda m: round(float(np.median(d[m])), 2) if m.any() else float("nan")
    return med(use & deep), med(use & ~deep), round(float((use & deep).sum() / max(1, use.sum())), 3)


def clamped(scene: Scene, c: float) -> Scene:
    """The scene with every container's end radii at most c x the local radius of curvature of its guide at
    that joint (piece lengths' mean / turn angle); root and tip ends are left as they are."""
    rows = scene.segments.copy()
    per = scene.source.segments
    p = np.concatenate([rows[:, 0:3].reshape(-1, per, 3), rows[per - 1::per, 4:7][:, None]], 1).astype(np.float64)
    d = np.diff(p, axis=1)
    h = np.linalg.norm(d, axis=2)
    u = d / h[..., None]
    turn = np.arccos(np.clip((u[:, 1:] * u[:, :-1]).sum(-1), -1.0, 1.0))
    limit = np.full(p.shape[:2], np.inf)
    limit[:, 1:-1] = c * 0.5 * (h[:, 1:] + h[:, :-1]) / np.maximum(turn, 1e-9)
    rows[:, 3] = np.minimum(rows[:, 3], limit[:, :-1].ravel())
    rows[:, 7] = np.minimum(rows[:, 7], limit[:, 1:].ravel())
    return Scene(rows, scene.origin, scene.name, scene.n_guides, scene.guide_colors)


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    ctx = create_headless().ctx
    path = str(HAIR_DATA / GROOM)
    p, _ = resolve_params(path, looks.REFERENCE_SETS)
    scene = build_scene(p)
    cam = Camera.from_params(p, scene, aspect=SIZE[0] / SIZE[1])
    explicit = ExplicitRenderer(ctx, budget_bytes=1 << 30)
    refs = {}
    for method in ("interpolated", "strands"):
        ref = strand_reference.build(p, scene, method=method)
        refs[method] = strand_reference.render(ctx, ref, p, cam, SIZE, explicit)
        explicit.release()
    explicit.release_targets()
    deep = inside(refs["interpolated"].ids[..., 0] > 0)
    renderer = Renderer(ctx)
    rows, shown = [], {}
    blend_k = children.blend.__defaults__
    for label, (sets, how) in VARIANTS.items():
        for seed in SEEDS:
            children.blend.__defaults__ = (how.get("k", children.NEIGHBOURS),)
            pv, _ = resolve_params(path, sets + [f"scene.seed={seed}"])
            t0 = time.perf_counter()
            sv = build_scene(pv)
            if "clamp" in how:
                sv = clamped(sv, how["clamp"])
            build_s = time.perf_counter() - t0
            renderer.set_scene(sv)
            frame = renderer.render_quality(pv, cam, SIZE, outputs=("color", "ids"))
            mask = frame.ids[..., 0] > 0
            ref_i = refs["interpolated"]
            deg, frac = looks.orientation_agreement(ref_i.color, ref_i.ids[..., 0] > 0, frame.color, mask)
            strands = refs["strands"]
            sdeg, _ = looks.orientation_agreement(strands.color, strands.ids[..., 0] > 0, frame.color, mask)
            row = {"variant": label, "sets": " ".join(sets), "seed": seed, "children": pv["scene.groom_children"],
                   "iou": round(looks.coverage_iou(ref_i.ids[..., 0] > 0, mask), 4), "deg": round(deg, 2),
                   "compared": round(frac, 3), "deg_vs_strands": round(sdeg, 2), "containers": sv.n_segments,
                   "build_s": round(build_s, 2)}
            row["deg_inside"], row["deg_rim"], row["compared_inside"] = split(ref_i, frame, deep)
            row["deg_vs_strands_inside"], row["deg_vs_strands_rim"], _ = split(strands, frame, deep)
            rows.append(row)
            print(" | ".join(f"{k} {v}" for k, v in row.items()), flush=True)
            if seed == SEEDS[0]:
                shown[label] = (frame.color, row)
    children.blend.__defaults__ = blend_k
    renderer.release_targets()
    (out / "rows.json").write_text(json.dumps(rows, indent=1))
    lines = ["| variant | children | containers | IoU median (range) | deg median (range) | deg vs strands median "
             "(range) | deg inside / rim (share of compared px inside) | deg vs strands inside / rim |",
             "|---|---:|---:|---|---|---|---|---|"]
    for label in VARIANTS:
        rs = [r for r in rows if r["variant"] == label]
        fig = lambda k, f: (f"{np.median([r[k] for r in rs]):{f}} ({min(r[k] for r in rs):{f}}-"
                            f"{max(r[k] for r in rs):{f}})")
        lines.append(f"| {label} | {rs[0]['children']} | {rs[0]['containers']:,} | {fig('iou', '.3f')} | "
                     f"{fig('deg', '.1f')} | {fig('deg_vs_strands', '.1f')} | "
                     f"{np.nanmedian([r['deg_inside'] for r in rs]):.1f} / "
                     f"{np.nanmedian([r['deg_rim'] for r in rs]):.1f} "
                     f"({np.median([r['compared_inside'] for r in rs]):.0%}) | "
                     f"{np.nanmedian([r['deg_vs_strands_inside'] for r in rs]):.1f} / "
                     f"{np.nanmedian([r['deg_vs_strands_rim'] for r in rs]):.1f} |")
    (out / "summary.md").write_text("\n".join(lines) + "\n")
    tiles = [("Curly_100: the file's strands alone", refs["strands"].color),
             ("interpolated reference (the judge)", refs["interpolated"].color)]
    for label in ("plain (groom_auto off)", "auto, 0 children", "auto (15 children, the automatic count)"):
        color, row = shown[label]
        tiles.append((f"{label}: IoU {row['iou']:.3f}, {row['deg']:.1f} deg, {row['deg_vs_strands']:.1f} deg off "
                      f"the strands (seed 1)", color))
    compose_sheet(tiles, out / "sheet.png", cols=len(tiles))
    print("\n".join(lines))


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "docs/bench/looks-children"))
