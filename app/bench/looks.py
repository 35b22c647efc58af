"""The ``looks`` suite: each shared groom rendered by the virtual fibers, judged against its own strands.

The reference is ``strand_reference``: the file's strands with child strands interpolated between them
(``REFERENCE``; the full level also shows the earlier "disc" reference, children in a disc around each
strand, whose rows carry no targets), drawn by the explicit baseline at the same camera, light and look.
Per groom and per variant of the parameters (``VARIANTS``: ``before``, the plain defaults of old; ``auto``,
per-groom fibers alone; ``after``, today's defaults), two numbers:

coverage IoU
    Coverage is the hit mask (fiber id != 0, the id output; ``--alpha`` writes the same pixels). Each mask
    is blurred with a Gaussian of sigma ``COVERAGE_BLUR_PX`` (2 px) and thresholded at 0.5, so a pixel
    counts as covered where at least half its 2 px neighbourhood is; IoU = |A and B| / |A or B| of the
    two thresholded masks (1 when both are empty).

orientation difference
    The direction hair runs in the picture, from the structure tensor of the shaded luminance: gradients
    of the image smoothed with sigma ``GRADIENT_SIGMA_PX`` (1 px), their outer products averaged with a
    Gaussian of sigma ``ORIENTATION_SCALE_PX`` (8 px). The tensor's principal direction is the gradient's;
    strands run perpendicular to it. Coherence (l1 - l2) / (l1 + l2) says how one-directional a pixel's
    neighbourhood is. Over pixels covered in both pictures (raw hit masks) whose coherence is at least
    ``COHERENCE_MIN`` (0.3) in both, the median absolute angle difference, mod 180 degrees (0 .. 90).

orientation against the strands (not judged)
    The same orientation figure against the file's strands alone (``strand_reference`` method "strands"),
    for every vfiber picture and every reference: does the hair run where the groom's own strands run? A
    reference is only a fair judge of orientation where it passes this itself; on Curly_100 the interpolated
    one does not (its children, copies of a hook translated across a disc as wide as the curl, shade into
    bands that cross the strands).

Each groom gets a contact sheet ``DIR/sheet_<groom>.png``: the strands alone | reference | one column per
variant, captioned with the figures; targets (issue 15): IoU >= 0.9 and orientation <= 10 degrees per groom.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

Row = dict[str, Any]
COVERAGE_BLUR_PX = 2.0
COVERAGE_THRESHOLD = 0.5
GRADIENT_SIGMA_PX = 1.0
ORIENTATION_SCALE_PX = 8.0
COHERENCE_MIN = 0.3
TARGET_IOU, TARGET_ORIENTATION_DEG = 0.9, 10.0
GROOMS = ("sintel_hair.tfx", "Bangs_100.hair", "Ratboy_mohawk.tfx", "harolongo.data", "Curly_100.ply")
# label -> --set assignments on top of the groom's own parameters; every one unfiltered (quality.filter = off,
# the default before #16): the suite judges the fibers a groom gets, and its figures were taken unfiltered
VARIANTS: dict[str, list[str]] = {
    # the plain defaults before fibers.groom_auto was turned on: 3,600 fibers per container, one per strand
    "before": ["fibers.groom_auto=false", "scene.groom_children=0", "quality.filter=off"],
    # the per-groom fiber defaults without interpolated children (the last candidate for the default)
    "auto": ["fibers.groom_auto=true", "scene.groom_children=0", "quality.filter=off"],
    # today's defaults: per-groom fibers, and interpolated children where containers fold (Curly_100)
    "after": ["fibers.groom_auto=true", "quality.filter=off"],
}
REFERENCE_SETS = ["fibers.groom_auto=false", "scene.groom_children=0", "quality.filter=off"]
"""The parameters the references (and the camera) are built from, whatever the product's defaults: the
reference takes its fiber count, width and R from the virtual scene (strand_reference.build), so without this
pin a change of defaults would move the judge along with the product."""
# the suite's reference (strand_reference.METHODS); the full level also shows "disc", the earlier one, untargeted
REFERENCE = "interpolated"


# --------------------------------------------------------------------------------------------------
# Metrics (numpy only)
# --------------------------------------------------------------------------------------------------
def gaussian_kernel(sigma: float) -> np.ndarray:
    if sigma <= 0:
        return np.ones(1)
    r = max(1, int(np.ceil(3.0 * sigma)))
    x = np.arange(-r, r + 1, dtype=np.float64)
    k = np.exp(-0.5 * (x / sigma) ** 2)
    return k / k.sum()


def gaussian_derivative_kernel(sigma: float) -> np.ndarray:
    """d/dx of the Gaussian, sampled, scaled so that it returns slope 1 on a unit ramp."""
    r = max(1, int(np.ceil(3.0 * sigma)))
    x = np.arange(-r, r + 1, dtype=np.float64)
    k = -x * np.exp(-0.5 * (x / sigma) ** 2)
    return k / -np.sum(k * x)


def _separable(img: np.ndarray, kernels: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Convolve along axis 0 with kernels[0], then along axis 1 with kernels[1]; edges reflected."""
    a = np.asarray(img, np.float64)
    for axis, k in ((0, kernels[0]), (1, kernels[1])):
        r = len(k) // 2
        if r == 0:
            a = a * k[0]
            continue
        pad = [(0, 0), (0, 0)]
        pad[axis] = (r, r)
        p = np.pad(a, pad, mode="reflect" if a.shape[axis] > r else "edge")
        p = np.moveaxis(p, axis, -1)
        win = np.lib.stride_tricks.sliding_window_view(p, len(k), axis=-1)
        a = np.moveaxis(win @ k[::-1], -1, axis)
    return a


def gaussian_blur(img: np.ndarray, sigma: float) -> np.ndarray:
    """Separable Gaussian blur of a 2-D array, edges reflected (a mask does not fade at the frame's edge)."""
    k = gaussian_kernel(sigma)
    return _separable(img, (k, k))


def blurred_coverage(mask: np.ndarray, blur_px: float = COVERAGE_BLUR_PX,
                     threshold: float = COVERAGE_THRESHOLD) -> np.ndarray:
    return gaussian_blur(np.asarray(mask, bool).astype(np.float64), blur_px) >= threshold


def coverage_iou(a: np.ndarray, b: np.ndarray, blur_px: float = COVERAGE_BLUR_PX,
                 threshold: float = COVERAGE_THRESHOLD) -> float:
    """IoU of two hit masks after the blur and threshold (1.0 when neither covers anything)."""
    if np.shape(a) != np.shape(b):
        raise ValueError(f"coverage_iou: masks of shapes {np.shape(a)} and {np.shape(b)}")
    ca, cb = blurred_coverage(a, blur_px, threshold), blurred_coverage(b, blur_px, threshold)
    union = int((ca | cb).sum())
    return 1.0 if union == 0 else float((ca & cb).sum() / union)


def luminance(rgb: np.ndarray) -> np.ndarray:
    """Rec. 709 luma of an (H, W, 3) picture, 0 .. 1 (uint8 in, or floats already 0 .. 1)."""
    c = np.asarray(rgb, np.float64)[..., :3]
    if np.asarray(rgb).dtype == np.uint8:
        c = c / 255.0
    return c @ np.array([0.2126, 0.7152, 0.0722])


def orientation_field(gray: np.ndarray, scale: float = ORIENTATION_SCALE_PX,
                      gradient_sigma: float = GRADIENT_SIGMA_PX) -> tuple[np.ndarray, np.ndarray]:
    """(direction, coherence) per pixel: the direction strands run, radians in [0, pi) from +x (columns)
    toward +y (rows, downward), perpendicular to the structure tensor's principal direction; coherence
    (l1 - l2) / (l1 + l2) in [0, 1], 0 where the picture is flat."""
    # derivative-of-Gaussian filters: central differences of the blurred picture lean oblique stripes of a
    # few pixels' period by degrees toward the axes; these stay within a fraction of one
    g, dg = gaussian_kernel(gradient_sigma), gaussian_derivative_kernel(gradient_sigma)
    gx = _separable(gray, (g, dg))
    gy = _separable(gray, (dg, g))
    jxx = gaussian_blur(gx * gx, scale)
    jyy = gaussian_blur(gy * gy, scale)
    jxy = gaussian_blur(gx * gy, scale)
    gradient_dir = 0.5 * np.arctan2(2.0 * jxy, jxx - jyy)
    direction = np.mod(gradient_dir + 0.5 * np.pi, np.pi)
    trace = jxx + jyy
    spread = np.sqrt((jxx - jyy) ** 2 + 4.0 * jxy ** 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        coherence = np.where(trace > 1e-12, spread / trace, 0.0)
    return direction, np.clip(coherence, 0.0, 1.0)


def angle_difference_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """|a - b| between undirected directions (radians), in degrees 0 .. 90."""
    d = np.mod(np.asarray(a) - np.asarray(b), np.pi)
    return np.degrees(np.minimum(d, np.pi - d))


def orientation_agreement(img_a: np.ndarray, mask_a: np.ndarray, img_b: np.ndarray, mask_b: np.ndarray,
                          scale: float = ORIENTATION_SCALE_PX,
                          coherence_min: float = COHERENCE_MIN) -> tuple[float, float]:
    """(median angle difference in degrees, fraction of pixels covered in both that were oriented enough to
    be compared). NaN when no pixel qualifies."""
    da, ca = orientation_field(luminance(img_a), scale)
    db, cb = orientation_field(luminance(img_b), scale)
    both = np.asarray(mask_a, bool) & np.asarray(mask_b, bool)
    use = both & (ca >= coherence_min) & (cb >= coherence_min)
    if not use.any():
        return float("nan"), 0.0
    return float(np.median(angle_difference_deg(da[use], db[use]))), float(use.sum() / max(1, both.sum()))


# --------------------------------------------------------------------------------------------------
# The suite
# --------------------------------------------------------------------------------------------------
def configs(level: str) -> list[dict]:
    if level == "smoke":
        return [{"groom": "Curly_100.ply", "size": (96, 54), "max_instances": 100_000}]
    if level == "quick":
        return [{"groom": g, "size": (320, 180), "max_instances": 1_000_000}
                for g in ("sintel_hair.tfx", "Curly_100.ply")]
    from .strand_reference import MAX_INSTANCES

    return [{"groom": g, "size": (640, 360), "max_instances": MAX_INSTANCES, "references": (REFERENCE, "disc")}
            for g in GROOMS]


def judge(ref_frame, frame) -> Row:
    """The suite's figures for one picture against the reference (both ``Frame``s with colour and ids)."""
    href, hv = ref_frame.ids[..., 0] > 0, frame.ids[..., 0] > 0
    deg, frac = orientation_agreement(ref_frame.color, href, frame.color, hv)
    both = href & hv
    luma = lambda f: round(float(luminance(f.color)[both].mean()), 4) if both.any() else None
    return {"iou": round(coverage_iou(href, hv), 4), "orientation_deg": round(deg, 2),
            "oriented_frac": round(frac, 4), "covered_reference": round(float(href.mean()), 4),
            "covered_virtual": round(float(hv.mean()), 4), "luma_reference": luma(ref_frame),
            "luma_virtual": luma(frame)}


def run(env, cfg: dict, variants: dict[str, list[str]] | None = None) -> list[Row]:
    """Rows per (reference, variant): ``cfg["references"]`` (default: the interpolated one alone) names the
    strand_reference methods to judge against, the first of them the suite's own (its rows carry the
    targets); each gets a column of the sheet."""
    from ..presets import resolve_params
    from ..render.camera import Camera
    from ..render.explicit import ExplicitRenderer
    from ..render.renderer import Renderer
    from ..fibers import ring_layout
    from ..scene.generators import build_scene
    from . import strand_reference
    from .grooms import HAIR_DATA

    variants = VARIANTS if variants is None else variants
    name, size = cfg["groom"], tuple(cfg["size"])
    path = HAIR_DATA / name
    if not path.exists():
        return [{"groom": name, "status": "skipped", "note": f"{path}: shared hair data not found"}]
    p, _ = resolve_params(str(path), REFERENCE_SETS)
    scene = build_scene(p)
    cam = Camera.from_params(p, scene, aspect=size[0] / size[1])
    explicit = ExplicitRenderer(env.ctx, budget_bytes=max(env.budget_bytes, 1 << 30))
    refs = []
    for method in cfg.get("references", (REFERENCE,)):
        t0 = time.perf_counter()
        ref = strand_reference.build(p, scene, max_instances=cfg.get("max_instances", strand_reference.MAX_INSTANCES),
                                     method=method, tip_taper=cfg.get("tip_taper", 0.0))
        build_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        ref_frame = strand_reference.render(env.ctx, ref, p, cam, size, explicit)
        refs.append((ref, ref_frame, build_s, time.perf_counter() - t0))
        explicit.release()                      # the next reference's 700 MB of rows is not added to these
    # the file's strands alone: not judged for coverage, only which way hair runs (STRANDS_CHECK)
    strands = strand_reference.build(p, scene, method="strands")
    strands_frame = strand_reference.render(env.ctx, strands, p, cam, size, explicit)
    explicit.release()
    explicit.release_targets()
    along = lambda f: round(orientation_agreement(strands_frame.color, strands_frame.ids[..., 0] > 0,
                                                  f.color, f.ids[..., 0] > 0)[0], 2)
    ref_along = [along(f) for _, f, _, _ in refs]
    renderer = Renderer(env.ctx)
    rows, shown, scenes = [], [], {_scene_key(p): scene}
    for label, sets in variants.items():
        pv, _ = resolve_params(str(path), list(sets))
        # a variant may rebuild the containers (scene.* keys) but is seen from the reference's camera
        key = _scene_key(pv)
        if key not in scenes:
            scenes[key] = build_scene(pv)
        renderer.set_scene(scenes[key])
        t0 = time.perf_counter()
        frame = renderer.render_quality(pv, cam, size, outputs=("color", "ids"))
        ms = round(1e3 * (time.perf_counter() - t0), 1)
        frame_along = along(frame)
        drawn = ring_layout(pv).fibers_per_container * scenes[key].n_guides     # this variant's own fibers
        for (ref, ref_frame, build_s, ref_s), reference_along in zip(refs, ref_along):
            row: Row = {"groom": name, "variant": label, "reference": ref.method, "sets": " ".join(sets),
                        "width": size[0], "height": size[1], **judge(ref_frame, frame),
                        "strands_deg": frame_along, "reference_strands_deg": reference_along,
                        "variant_fibers": drawn,
                        "virtual_fibers": ref.virtual_fibers, "reference_fibers": ref.fibers,
                        "reference_strands": ref.strands, "children": round(ref.children),
                        "reference_segments": ref.n_segments, "reference_fiber_radius": round(ref.fiber_radius, 4),
                        "capped": "yes" if ref.capped else "no", "reference_tip_taper": ref.tip_taper,
                        "reference_clump": ref.clump, "reference_length_variation": ref.length_variation,
                        "reference_tip_width": ref.tip_width, "reference_dropped": ref.dropped,
                        "reference_build_s": round(build_s, 2),
                        "reference_ms": round(1e3 * ref_s, 1), "ms": ms}
            rows.append(row)
        shown.append((label, frame.color, rows[-len(refs)]))
    renderer.release_targets()
    out = getattr(env, "out", None)
    if out:
        write_sheet(Path(out) / f"sheet_{Path(name).stem}.png", name, [(r, f.color) for r, f, _, _ in refs], shown,
                    (strands, strands_frame.color))
    return rows


def _scene_key(p) -> tuple:
    return tuple(sorted((k, str(v)) for k, v in p.values.items() if k.startswith("scene.")))


def sheet_tiles(groom: str, refs, shown: list[tuple[str, np.ndarray, Row]], strands=None):
    """The sheet's columns: the file's strands alone (``(Reference, picture)``, when given), each reference
    (the suite's own first), then one per variant (label, picture, its row of figures against the first
    reference and its angle to the strands)."""
    tiles = []
    if strands is not None:
        tiles.append((f"{groom}: its {strands[0].strands:,} file strands alone", strands[1]))
    for ref, color in refs:
        capped = f", capped from {ref.virtual_fibers:,}" if ref.capped else ""
        how = (f"{ref.strands:,} file strands + interpolated children = {ref.fibers:,} fibers{capped}"
               if ref.method == "interpolated" else
               f"{ref.strands:,} file strands x {ref.fibers_per_row:,} disc children = {ref.fibers:,} fibers{capped}")
        tiles.append((f"{groom} reference ({ref.method}): {how}", color))
    for label, color, row in shown:
        fibers = row.get("variant_fibers", row["virtual_fibers"])
        caption = (f"{label}: vfiber {fibers:,} fibers; IoU {row['iou']:.3f}, orientation "
                   f"{row['orientation_deg']:.1f} deg")
        if row.get("strands_deg") is not None:
            caption += f"; {row['strands_deg']:.1f} deg off the strands"
        tiles.append((caption, color))
    return tiles


def write_sheet(path: Path, groom: str, refs, shown, strands=None) -> Path:
    from ..contact_sheet import compose_sheet

    tiles = sheet_tiles(groom, refs, shown, strands)
    path.parent.mkdir(parents=True, exist_ok=True)
    compose_sheet(tiles, path, cols=len(tiles))
    return path


COLUMNS = [("groom", "groom"), ("variant", "variant"), ("reference", "reference"), ("status", "status"),
           ("iou", "coverage IoU"),
           ("orientation_deg", "orientation median deg"), ("oriented_frac", "compared px"),
           ("strands_deg", "vfiber deg vs strands"), ("reference_strands_deg", "reference deg vs strands"),
           ("variant_fibers", "vfiber fibers"), ("virtual_fibers", "fibers matched by the reference"),
           ("reference_fibers", "reference fibers"),
           ("children", "children/strand"), ("capped", "capped"), ("reference_fiber_radius", "child radius / R"),
           ("covered_reference", "covered ref"), ("covered_virtual", "covered vfiber"),
           ("luma_reference", "luma ref"), ("luma_virtual", "luma vfiber"),
           ("reference_ms", "ref ms"), ("ms", "vfiber ms/frame")]

NOTES = (f"Reference: the groom's own strands plus child strands (app/bench/strand_reference.py) through the "
         f"explicit baseline, same camera, light and look. reference 'interpolated' (the suite's, targets judged "
         f"on it): children rooted between the strands' roots, each blended from its 4 nearest strands, mild clump, "
         f"length variation, tapered tips; 'disc': children in a disc of radius R around each strand, parallel to "
         f"it, full length (the earlier reference, shown for comparison). coverage IoU: hit masks blurred with sigma "
         f"{COVERAGE_BLUR_PX:g} px, thresholded at {COVERAGE_THRESHOLD:g}. orientation: structure tensor of the "
         f"shaded luminance (gradient sigma {GRADIENT_SIGMA_PX:g} px, tensor sigma {ORIENTATION_SCALE_PX:g} px), "
         f"median |angle difference| mod 180 deg over pixels covered in both with coherence >= "
         f"{COHERENCE_MIN:g} in both; compared px: that set's fraction of the pixels covered in both. luma: mean "
         f"Rec. 709 luma of the 8-bit picture over pixels covered in both (not judged; for the colour work). deg vs "
         f"strands: the same orientation figure against the file's strands alone (strand_reference method "
         f"'strands', each strand one fiber 0.25 R wide, no children), for vfiber and for the reference: whether a "
         f"picture's hair runs where the groom's own strands run (not judged). capped: "
         f"the reference drew fewer fibers than vfiber (strand_reference.MAX_INSTANCES), each widened (child "
         f"radius / R, at the root) to keep the projected cross-section. children/strand: reference fibers per file "
         f"strand. Sheets: sheet_<groom>.png.")


def targets(rows: list[Row]) -> list[Row]:
    out: list[Row] = []
    for r in rows:
        if r.get("status", "ok") != "ok" or r.get("iou") is None:
            continue
        if r.get("reference", REFERENCE) != REFERENCE:      # the disc reference's rows are shown, not judged
            continue
        out.append({"target": f"{r['groom']} ({r['variant']}): coverage IoU >= {TARGET_IOU:g}",
                    "measured": f"{r['iou']:.3f}", "met": r["iou"] >= TARGET_IOU})
        raw = r.get("orientation_deg")
        deg = float(raw) if isinstance(raw, (int, float)) else float("nan")
        ok = not np.isnan(deg)
        out.append({"target": f"{r['groom']} ({r['variant']}): orientation <= {TARGET_ORIENTATION_DEG:g} deg",
                    "measured": f"{deg:.1f} deg" if ok else "nothing to compare",
                    "met": (deg <= TARGET_ORIENTATION_DEG) if ok else None})
    return out


def plot(rows: list[Row], path: Path, machine, plt, save) -> None:
    """IoU and orientation per groom, variant and reference, the targets dashed."""
    ok = [r for r in rows if r.get("status", "ok") == "ok" and r.get("iou") is not None]
    grooms = list(dict.fromkeys(r["groom"] for r in ok))
    label = lambda r: f"{r['variant']} vs {r.get('reference', REFERENCE)} reference"
    variants = list(dict.fromkeys(label(r) for r in ok))
    xs = np.arange(len(grooms))
    w = 0.8 / max(1, len(variants))
    fig, (a, b) = plt.subplots(1, 2, figsize=(12, 4.5))
    for i, v in enumerate(variants):
        by = {r["groom"]: r for r in ok if label(r) == v}
        off = (i - (len(variants) - 1) / 2) * w
        a.bar(xs + off, [by.get(g, {}).get("iou") or 0 for g in grooms], w, label=v)
        b.bar(xs + off, [by.get(g, {}).get("orientation_deg") or 0 for g in grooms], w, label=v)
    a.axhline(TARGET_IOU, color="k", ls="--", lw=0.8, label=f"target {TARGET_IOU:g}")
    b.axhline(TARGET_ORIENTATION_DEG, color="k", ls="--", lw=0.8, label=f"target {TARGET_ORIENTATION_DEG:g} deg")
    a.set_ylim(0, 1)
    a.set_title("coverage IoU against the strand reference (2 px blur)", fontsize=9)
    b.set_title("orientation: median angle difference, degrees (8 px structure tensor)", fontsize=9)
    for ax in (a, b):
        ax.set_xticks(xs, grooms, rotation=15, fontsize=7)
        ax.grid(True, axis="y", alpha=0.3)
        ax.legend(fontsize=7)
    save(fig, path, machine)
