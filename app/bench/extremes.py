"""``vfiber bench extremes``: numerical stability at the extremes, measured case by case.

Each case renders float outputs (fiber ids, depth, normals, the shaded colour into a float target) and
holds them against the float64 reference (``app.reference``) or against the same scene in a benign
configuration; it returns a ``Case`` with a pass/fail, the measured rate and notes. ``run_extremes``
runs them all and writes ``extremes.md`` (the table), ``extremes.json`` and ``extremes.png`` (a contact
sheet of each case's worst image). ``quick`` is the reduced set the tests run (tests/extremes/); the
full set adds the slow configurations (64 rings at 0.01 degrees with curl and twist, beyond-spec
distances) and larger images.

    python -m app.bench.extremes [--quick] [--out DIR] [--case N ...]

The cases (the issue's numbering):
  1 scene and camera translated by 1e4 and 1e6        7 axes along +-X, +-Y, +-Z and 1e-7 rad off them
  2 camera distance / fiber radius 1e2 .. 1e5          8 bends of 0, 1, 30, 90, 179 degrees
  3 fiber radius 1e-6, 1e-12, 1e-30, 0                 9 jitter at its maximum and just above
  4 64 rings at 0.01 degrees: exact == brute           10 camera inside a container; near 1e-4, far 1e6
  5 grazing rays at R (1 +- 1e-k), k = 3..6            11 temporal stability; the thesis hash's flips
  6 rays along the axis and tilted 1e-7 .. 1e-3        12 slider ends, pairwise extremes: exact == brute
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import shutil
import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import moderngl
import numpy as np

from .. import reference          # the float64 judge; the model itself comes from app.fibers
from ..fibers import (CH_ANGULAR, CH_LENGTH, CH_RADIAL, CH_TINT, all_fibers, fiber_randoms, ring_layout,
                     thesis_random)
from ..params import SPEC, ParamError, Params, max_fiber_radius
from ..render.camera import Camera
from ..render.renderer import LOOP_CAP, MAX_RINGS, Renderer, ring_uniforms
from ..scene.containers import SINGULAR_AXIS, Scene, orthonormal_x
from ..scene.generators import build_scene, guide_polyline

# ---------------------------------------------------------------------------------------------------
# Float rendering and comparison
# ---------------------------------------------------------------------------------------------------


@dataclass
class FloatFrame:
    color: np.ndarray          # (H, W, 4) float32: shaded colour (premultiplied), coverage
    ids: np.ndarray            # (H, W, 4) uint32: guide + 1, ring, fiber, segment
    geom: np.ndarray           # (H, W, 4) float32: world normal, distance along the ray
    iters: np.ndarray | None   # (H, W) most loop passes of a fragment (LOOP_CAP: a run-out)
    draws: int

    @property
    def hit(self) -> np.ndarray:
        return self.ids[..., 0] > 0

    def finite(self) -> bool:
        return bool(np.isfinite(self.color).all() and np.isfinite(self.geom).all())

    def nonfinite(self) -> int:
        return int((~np.isfinite(self.color)).any(-1).sum() + (~np.isfinite(self.geom)).any(-1).sum())


class FloatRenderer(Renderer):
    """The renderer with its colour target in float32, so a NaN or an Inf in the shading shows instead of
    being clamped to 8 bits. Everything else is the renderer's own path."""

    COLOR_DTYPE = "f4"

    def render_float(self, p: Params, cam: Camera, size: tuple[int, int], mode: str = "exact",
                     offset=(0.0, 0.0), iters: bool = False) -> FloatFrame:
        outputs = ("ids", "geom", "iters") if iters else ("ids", "geom")
        frame = self.render(p, cam, size, outputs=outputs, mode=mode, offset=offset, antialias=False)
        w, h = size
        raw = self.targets(size).color_attachments[0].read()
        color = np.frombuffer(raw, np.float32).reshape(h, w, 4)[::-1].copy()
        return FloatFrame(color, frame.ids, frame.geom, frame.iters, frame.draws)


def ids3(ids: np.ndarray) -> np.ndarray:
    """(H, W, 3) int64: guide + 1, ring, fiber; (0, -1, -1) on a miss."""
    ids = ids.astype(np.int64)
    hit = ids[..., 0] > 0
    return np.stack([ids[..., 0], np.where(hit, ids[..., 1], -1), np.where(hit, ids[..., 2], -1)], -1)


def id_disagreement(ref: np.ndarray, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(wrong, shown): the pixels where float64 (``ref``, ids3 form) or the GPU (``ids``) shows a fiber, and
    those among them whose fiber differs."""
    shown = (ref[..., 0] > 0) | (ids[..., 0] > 0)
    return ~np.all(ref == ids3(ids), -1) & shown, shown


def reference_ids(scene: Scene, p: Params, cam: Camera, size, offset=(0.0, 0.0)):
    """Float64 brute force for every pixel ray: (ids3 image, Hits)."""
    w, h = size
    ro, rd = cam.rays(w, h, offset)
    hits = reference.brute_nearest(scene, p, ro, rd, t_near=cam.near)
    g = np.where(hits.hit, hits.guide + 1, 0)
    return np.stack([g, hits.ring, hits.fiber], -1).reshape(h, w, 3), hits


def id_image(ids: np.ndarray) -> np.ndarray:
    from ..render.debug_views import fiber_id_image

    return fiber_id_image(ids)


def mark(img: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """The image with ``mask`` pixels in magenta."""
    out = img.copy()
    out[mask] = (255, 0, 255)
    return out


@dataclass
class Case:
    number: int
    title: str
    passed: bool
    rate: float                     # the measured rate (a fraction unless ``measure`` says otherwise)
    measure: str                    # what ``rate`` counts
    threshold: str                  # what passing means
    notes: str = ""
    details: dict = field(default_factory=dict)
    images: list = field(default_factory=list)     # (caption, (H, W, 3) uint8)
    seconds: float = 0.0

    def row(self) -> dict:
        d = asdict(self)
        d.pop("images")
        return d


class Lab:
    """One context, one float renderer, the level (quick or full) and a place for a case's images."""

    def __init__(self, ctx: moderngl.Context, quick: bool = True, verbose: bool = False):
        self.ctx = ctx
        self.r = FloatRenderer(ctx)
        self.quick = quick
        self.verbose = verbose

    def log(self, text: str) -> None:
        if self.verbose:
            print(f"      {text}", flush=True)

    def show(self, scene: Scene) -> None:
        self.r.set_scene(scene)

    def render(self, p, cam, size, mode="exact", offset=(0.0, 0.0), iters=False) -> FloatFrame:
        return self.r.render_float(p, cam, size, mode, offset, iters)


def _unit(v) -> np.ndarray:
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v)


def _pct(x: float) -> str:
    return f"{100.0 * x:.3g}%"


# ---------------------------------------------------------------------------------------------------
# 1. translation
# ---------------------------------------------------------------------------------------------------
BENT_GUIDES = [np.array([[x, y, 0.0], [x + 0.1, y, 1.0], [x + 0.3, y + 0.1, 2.0]])
               for x in (-0.6, 0.0, 0.6) for y in (-0.5, 0.5)]
SMALL = {"fibers.rings": 6, "fibers.phi_step": 3.0, "fibers.fiber_radius": 0.03, "fibers.length_jitter": 0.3}


def case_translation(lab: Lab) -> Case:
    size = (96, 72) if lab.quick else (192, 144)
    p = Params(SMALL)
    base = Scene.from_polylines(BENT_GUIDES, 0.25)
    cam0 = Camera([3.5, -2.5, 1.8], [0, 0, 1.0], 35, 0.5, 20)
    lab.show(base)
    f0 = lab.render(p, cam0, size)
    direction = np.array([1.0, -0.7, 0.3])
    offsets = [1e4, 1e6] + ([] if lab.quick else [1e7, 1e8])
    worst, rows, images, finite = 0.0, {}, [], f0.finite()
    for off in offsets:
        o = off * direction
        cam = Camera(cam0.position + o, cam0.target + o, 35, 0.5, 20)
        for how, scene in (("translated", base.translated(o)),
                           ("from world polylines", Scene.from_polylines([g + o for g in BENT_GUIDES], 0.25))):
            lab.show(scene)
            f = lab.render(p, cam, size)
            finite &= f.finite()
            differ = np.any(f.ids[..., :3] != f0.ids[..., :3], -1)
            depth = np.abs(f.geom[..., 3] - f0.geom[..., 3])[f0.hit]
            rows[f"{off:g} {how}"] = {"ids_differ": float(differ.mean()),
                                      "depth_max_rel": float((depth / f0.geom[..., 3][f0.hit]).max())}
            if off <= 1e6:
                worst = max(worst, float(differ.mean()))
            if differ.any() or off == offsets[-1] and how == "translated":
                images.append((f"1: {off:g} {how}", mark(id_image(f.ids), differ)))
    # what float32 world positions would cost: the same scene stored relative to the world origin
    o = 1e6 * direction
    lab.show(Scene.from_polylines([g + o for g in BENT_GUIDES], 0.25, origin=np.zeros(3)))
    bad = lab.render(p, Camera(cam0.position + o, cam0.target + o, 35, 0.5, 20), size)
    misuse = float(np.any(bad.ids[..., :3] != f0.ids[..., :3], -1).mean())
    images.append(("1: float32 world positions at 1e6 (what not to do)", id_image(bad.ids)))
    return Case(1, "scene and camera translated by 1e4, 1e6", worst < 1e-3 and finite, worst,
                "pixels whose fiber id differs from the origin-centred render (worst of 1e4, 1e6)",
                "< 0.1%, all finite",
                f"ids identical up to {max(offsets):g}; depth identical; stored relative to the world origin "
                f"instead, 1e6 would change {_pct(misuse)} of the ids",
                {"offsets": rows, "float32_world_misuse": misuse}, images[:2])


# ---------------------------------------------------------------------------------------------------
# 2. camera distance / fiber radius
# ---------------------------------------------------------------------------------------------------
def case_distance(lab: Lab) -> Case:
    p = Params({"fibers.rings": 4, "fibers.phi_step": 15.0, "fibers.fiber_radius": 0.02,
                "fibers.length_jitter": 0.5})
    rf = 0.02
    size = (64, 64) if lab.quick else (96, 96)
    views = 2 if lab.quick else 4
    rng = np.random.default_rng(1)
    axis = _unit([0.3, -0.5, 0.8])
    scene = Scene.from_polylines([np.array([-1.5 * axis, 1.5 * axis])], 1.0)
    lab.show(scene)
    ratios = [1e2, 1e3, 1e4, 1e5] + ([] if lab.quick else [1e6])
    rates, images, finite = {}, [], True
    for k in ratios:
        D = k * rf
        bad = total = 0
        for _ in range(views):
            v = rng.normal(size=3)
            v -= axis * (v @ axis)
            v = _unit(_unit(v) + 0.3 * axis * rng.uniform(-1, 1))
            target = axis * rng.uniform(-0.5, 0.5)
            fov = math.degrees(2 * math.atan(1.6 / D)) if D > 1.7 else 80.0
            cam = Camera(target + D * v, target, fov, max(D - 3.0, D * 1e-3), D + 3.0)
            f = lab.render(p, cam, size)
            finite &= f.finite()
            ref, _ = reference_ids(scene, p, cam, size)
            wrong = (ref[..., 0] > 0) != f.hit
            bad += int(wrong.sum())
            total += wrong.size
        rates[f"{k:g}"] = bad / total
        if k == 1e5 or k == max(ratios):
            images.append((f"2: distance {k:g} fiber radii", mark(id_image(f.ids), wrong)))
    worst = max(v for k, v in rates.items() if float(k) <= 1e5)
    beyond = f"; at 1e6 (outside the spec) {_pct(rates['1e+06'])}" if "1e+06" in rates else ""
    return Case(2, "camera distance / fiber radius 1e2 .. 1e5", worst < 2e-3 and finite, worst,
                "rays whose hit/miss differs from float64 (worst distance)", "< 0.2%",
                "by distance: " + ", ".join(f"{k}: {_pct(v)}" for k, v in rates.items()) + beyond,
                {"rates": rates}, images)


# ---------------------------------------------------------------------------------------------------
# 3. tiny and zero fiber radius
# ---------------------------------------------------------------------------------------------------
def case_radius(lab: Lab) -> Case:
    size = (64, 48) if lab.quick else (128, 96)
    scene = Scene.from_polylines(BENT_GUIDES, 0.25)
    lab.show(scene)
    cam = Camera([3.5, -2.5, 1.8], [0, 0, 1.0], 35, 0.5, 20)
    radii = [0.01, 1e-6, 1e-12, 1e-30, 0.0]
    problems, counts, checked = [], {}, 0
    bg_p = Params({})
    empty = None
    variants = [(rings, rj, shape) for rings in (6, 8) for rj in (0.5, 1.0) for shape in (False, True)]
    if lab.quick:
        variants = [v for v in variants if not (v[2] and v[0] == 6)]
    for rings, rj, shaped in variants:
        for mode in (("exact", "brute") if shaped else ("exact", "fast", "brute")):
            seq = []
            for rf in radii:
                values = {"fibers.rings": rings, "fibers.phi_step": 3.0, "fibers.fiber_radius": rf,
                          "fibers.radial_jitter": rj, "fibers.angular_jitter": 1.0}
                if shaped:
                    values.update({"shape.curl_amplitude": 0.3, "shape.twist": 0.5})
                p = Params(values)
                lay = ring_layout(p)
                if not all(np.isfinite(getattr(lay, k)).all() for k in ("rho", "max_dr", "max_dphi", "reach")):
                    problems.append(f"layout not finite: rings {rings} jitter {rj} radius {rf:g}")
                f = lab.render(p, cam, size, mode)
                checked += 1
                if not f.finite():
                    problems.append(f"{f.nonfinite()} non-finite pixels: {mode} rings {rings} radius {rf:g}")
                seq.append(int(f.hit.sum()))
                if rf == 0.0:
                    if f.hit.any() or (f.color != 0).any() or (f.geom != 0).any():
                        problems.append(f"radius 0 drew {int(f.hit.sum())} pixels: {mode} rings {rings} "
                                        f"jitter {rj}")
                    img = lab.r.render(p, cam, size, outputs=("color",), mode=mode).color
                    if empty is None:
                        empty = np.broadcast_to(np.round(np.clip(np.asarray(bg_p["look.background"]), 0, 1)
                                                         ** (1 / 2.2) * 255).astype(np.uint8), img.shape)
                    if (img != empty).any():
                        problems.append(f"radius 0 colour is not the empty image: {mode} rings {rings}")
            counts[f"rings {rings} jitter {rj} {'curved' if shaped else 'straight'} {mode}"] = seq
            if any(b > a for a, b in zip(seq, seq[1:])):
                problems.append(f"coverage grew as the radius shrank: {seq} ({mode}, rings {rings}, jitter {rj})")
    p = Params({"fibers.rings": 8, "fibers.phi_step": 3.0, "fibers.fiber_radius": 1e-6,
                "fibers.radial_jitter": 1.0})
    img = id_image(lab.render(p, cam, size).ids)
    return Case(3, "fiber radius 1e-6, 1e-12, 1e-30, 0", not problems, len(problems) / max(1, checked),
                "renders with a non-finite value, a radius-0 fiber or growing coverage", "none",
                ("coverage (pixels) for radius " + ", ".join(f"{r:g}" for r in radii) + ": "
                 + "; ".join(f"{k}: {v}" for k, v in list(counts.items())[:3]) + " ..."
                 + ("" if not problems else " PROBLEMS: " + "; ".join(problems[:4]))),
                {"coverage": counts, "problems": problems}, [("3: radius 1e-6, rings 8, full jitter", img)])


# ---------------------------------------------------------------------------------------------------
# 4. very many fibers
# ---------------------------------------------------------------------------------------------------
def many_fiber_configs(quick: bool) -> list[tuple[str, dict, tuple[int, int], bool]]:
    """(name, parameters, image size, slow)."""
    top = 0.5 / 64
    configs = [
        ("64 rings, 0.01 deg, thickest fibers", {"fibers.rings": 64, "fibers.phi_step": 0.01,
                                                  "fibers.fiber_radius": top}, (10, 10), False),
        ("1 ring, 0.05 deg, ellipsoid 1", {"fibers.rings": 1, "fibers.phi_step": 0.05,
                                           "fibers.fiber_radius": 1e-4, "shape.ellipsoid": 1.0}, (12, 12), False),
        ("64 rings, 0.01 deg, thin fibers, full jitter", {"fibers.rings": 64, "fibers.phi_step": 0.01,
                                                          "fibers.fiber_radius": 1e-4, "fibers.radial_jitter": 1.0,
                                                          "fibers.angular_jitter": 1.0}, (20, 20), True),
        ("1 ring, 0.01 deg, ellipsoid 1", {"fibers.rings": 1, "fibers.phi_step": 0.01,
                                           "fibers.fiber_radius": 1e-5, "shape.ellipsoid": 1.0}, (16, 16), True),
        ("64 rings, 0.01 deg, curl 0.5, twist 8", {"fibers.rings": 64, "fibers.phi_step": 0.01,
                                                    "fibers.fiber_radius": 1e-4, "shape.curl_amplitude": 0.5,
                                                    "shape.twist": 8.0}, (4, 4), True),
    ]
    return [c for c in configs if not (quick and c[3])]


def check_exact_equals_brute(lab: Lab, p: Params, cam: Camera, size, modes=("exact", "fast", "brute")):
    """(exact != brute pixels, fast coverage != exact, pixels with a loop run-out, draws, frames)."""
    frames = {m: lab.render(p, cam, size, m, iters=True) for m in modes}
    e, b = frames["exact"], frames["brute"]
    differ = np.any(e.ids[..., :3] != b.ids[..., :3], -1)
    fast = int((frames["fast"].hit != e.hit).sum()) if "fast" in frames else 0
    runout = sum(int((f.iters >= LOOP_CAP).sum()) for f in frames.values())
    finite = all(f.finite() for f in frames.values())
    return differ, fast, runout, finite, frames


def case_many_fibers(lab: Lab) -> Case:
    scene = Scene.from_polylines([np.array([[0, 0, 0], [0, 0, 2.0]])], 1.0)
    lab.show(scene)
    cam = Camera([2.2, 0.6, 1.8], [0, 0, 1.0], 40, 0.5, 20)
    notes, worst, ok, images, details = [], 0.0, True, [], {}
    for name, values, size, _ in many_fiber_configs(lab.quick):
        p = Params(values)
        t = time.perf_counter()
        differ, fast, runout, finite, frames = check_exact_equals_brute(lab, p, cam, size)
        e = frames["exact"]
        rate = float(differ.mean())
        worst = max(worst, rate)
        ok &= rate == 0 and runout == 0 and finite and fast == 0
        fibers = ring_layout(p).fibers_per_container
        details[name] = {"fibers": fibers, "differ": rate, "runout_pixels": runout, "fast_coverage_differs": fast,
                         "exact_draws": e.draws, "brute_draws": frames["brute"].draws,
                         "exact_iters_max": float(e.iters.max()), "seconds": time.perf_counter() - t}
        notes.append(f"{name} ({fibers:,} fibers): exact {e.draws} draws, brute {frames['brute'].draws}, "
                     f"{int(differ.sum())} px differ, {runout} run-outs")
        images.append((f"4: {name}", mark(id_image(e.ids), differ)))
    return Case(4, "64 rings, phi_step 0.01: exact == brute, no loop runs out", ok, worst,
                "pixels where exact differs from brute (worst layout)", "0, no run-out, fast covers the same",
                "; ".join(notes), details, images[:2])


# ---------------------------------------------------------------------------------------------------
# 5. grazing rays
# ---------------------------------------------------------------------------------------------------
def case_grazing(lab: Lab) -> Case:
    K = 4
    axis = _unit([0.3, -0.5, 0.8])
    size = (32, 64) if lab.quick else (48, 128)
    origins = [np.array([1e3, 2e3, -5e2])] + ([] if lab.quick else [np.array([1e6, 2e6, -5e5]), np.zeros(3)])
    bad = total = outside = 0
    worst_margin, images, details = 0.0, [], {}
    for origin in origins:
        for k in (3, 4, 5, 6):
            eps = 0.5 * 10.0 ** -k
            p0 = Params({"fibers.rings": K, "fibers.phi_step": 3.0, "fibers.fiber_radius": 0.1,
                         "fibers.radial_jitter": 1.0, "fibers.angular_jitter": 1.0, "fibers.length_jitter": 0.0})
            lay = ring_layout(p0)
            u = fiber_randoms(lay, 0, np.zeros(lay.n[0], int), np.arange(lay.n[0]), CH_RADIAL)
            j = int(np.argmax(u))
            # the fiber radius that puts the outermost fiber's edge eps inside the wall:
            # its extent is 1 - (1 - u) (1/K - 2 rf)
            rf = (1.0 / K - eps / (1.0 - u[j])) / 2.0
            p = p0.replace(**{"fibers.fiber_radius": rf})
            lay = ring_layout(p)
            _, _, cx, cy, _ = all_fibers(lay, 0)
            scene = Scene.from_polylines([np.array([-2 * axis, 2 * axis])], 1.0, origin=np.zeros(3)).translated(origin)
            lab.show(scene)
            seg = reference.segment(scene.segments[0])
            frame_m = np.stack([seg.ex, seg.ey, seg.ez])
            phi = math.atan2(cy[j], cx[j])
            for dphi in (0.0, 0.02):         # at the fiber that reaches the wall, and between fibers
                n = math.cos(phi + dphi) * seg.ex + math.sin(phi + dphi) * seg.ey
                m = np.cross(seg.ez, n)
                target = scene.origin + seg.p0 + 2.0 * seg.ez + n
                cam = Camera(target - 3.0 * m, target, math.degrees(2 * math.atan(4 * eps / 3.0)), 0.1, 10, up=n)
                f = lab.render(p, cam, size)
                ref, _ = reference_ids(scene, p, cam, size)
                ro, rd = cam.rays(*size)
                o = (ro - scene.origin - seg.p0) @ frame_m.T
                d = rd @ frame_m.T
                dxy = d[:, :2] / np.linalg.norm(d[:, :2], axis=1, keepdims=True)
                b = np.abs(o[:, 0] * dxy[:, 1] - o[:, 1] * dxy[:, 0])         # impact parameter / R
                dist = np.abs((o[:, None, 0] - cx[None]) * dxy[:, None, 1]
                              - (o[:, None, 1] - cy[None]) * dxy[:, None, 0])
                margin = np.minimum(np.abs(b - 1.0), np.abs(dist - rf).min(1)).reshape(size[1], size[0])
                b = b.reshape(size[1], size[0])
                wrong = (ref[..., 0] > 0) != f.hit
                bad += int((wrong & (margin > 1e-5)).sum())
                total += int((margin > 1e-5).sum())
                outside += int((f.hit & (b > 1.0)).sum())
                if wrong.any():
                    worst_margin = max(worst_margin, float(margin[wrong].max()))
                details[f"{origin[0]:g} k={k} dphi={dphi}"] = {"wrong": int(wrong.sum()), "gpu_hits": int(f.hit.sum()),
                                                               "ref_hits": int((ref[..., 0] > 0).sum())}
                if k == 6 and dphi == 0.0 and not images:
                    images.append(("5: grazing, k = 6 (magenta: differs from float64)", mark(id_image(f.ids), wrong)))
    rate = bad / max(1, total)
    return Case(5, "grazing rays at R (1 +- 1e-k), k = 3..6", bad == 0 and outside == 0, rate,
                "rays with margin > 1e-5 R whose hit/miss differs from float64", "0; no fiber hit outside",
                f"{outside} fiber hits outside the container; disagreements only within {worst_margin:.2g} R of an "
                f"edge (float32 resolution)", details, images)


# ---------------------------------------------------------------------------------------------------
# 6. rays along the axis
# ---------------------------------------------------------------------------------------------------
def case_axis_rays(lab: Lab) -> Case:
    p = Params({"fibers.rings": 6, "fibers.phi_step": 6.0, "fibers.fiber_radius": 0.04, "fibers.length_jitter": 0.3})
    size = (33, 33) if lab.quick else (65, 65)        # odd: the centre pixel's ray is exactly on the axis
    axes = [(np.array([0, 0, 1.0]), 0.0), (_unit([1, 1, 1.0]), 0.0), (np.array([0, 0, 1.0]), 0.6)]
    if not lab.quick:
        axes += [(np.array([1.0, 0, 0]), 0.0), (_unit([0.3, -0.5, 0.8]), 0.95)]
    dists = (5.0, 100.0) if lab.quick else (5.0, 100.0, 1000.0)
    tilts = (0.0, 1e-7, 1e-5, 1e-3) if lab.quick else (0.0, 1e-7, 1e-6, 1e-5, 1e-4, 1e-3)
    bad = hits = nonfinite = holes = 0
    images, details = [], {}
    for axis, taper in axes:
        scene = Scene.from_polylines([np.array([np.zeros(3), 2.0 * axis])], 1.0, taper=taper)
        lab.show(scene)
        perp = _unit(np.cross(axis, [0.3, 0.5, 0.7]))
        for dist, tilt, sign in itertools.product(dists, tilts, (1, -1)):
            d = (math.cos(tilt) * axis + math.sin(tilt) * perp) * sign
            target = axis * 1.0
            fov = math.degrees(2 * math.atan(1.2 / dist))
            cam = Camera(target + dist * d, target, fov, dist * 0.5, dist * 2, up=perp)
            f = lab.render(p, cam, size)
            ref, _ = reference_ids(scene, p, cam, size)
            wrong, shown = id_disagreement(ref, f.ids)
            bad += int(wrong.sum())
            hits += int(shown.sum())
            holes += int(((ref[..., 0] > 0) & ~f.hit).sum())
            nonfinite += f.nonfinite()
            key = (f"axis {np.round(axis, 2).tolist()} taper {taper:g} dist {dist:g} tilt {tilt:g} "
                   f"{'+' if sign > 0 else '-'}")
            details[key] = int(wrong.sum())
            if (wrong.any() or not images) and len(images) < 2:
                images.append((f"6: {key}", mark(id_image(f.ids), wrong)))
    rate = bad / max(1, hits)
    return Case(6, "rays along the axis, tilted 1e-7 .. 1e-3 rad", rate < 1e-3 and nonfinite == 0, rate,
                "hit pixels whose fiber differs from float64 (caps, discs)", "< 0.1%, no NaN",
                f"{nonfinite} non-finite pixels, {holes} float64 hits missing on the GPU, over {hits} hit pixels "
                f"(camera 5 to {max(dists):g} radii away)", details, images)


# ---------------------------------------------------------------------------------------------------
# 7. axis-aligned containers
# ---------------------------------------------------------------------------------------------------
AXES = {"+x": [1, 0, 0], "-x": [-1, 0, 0], "+y": [0, 1, 0], "-y": [0, -1, 0], "+z": [0, 0, 1], "-z": [0, 0, -1]}


def case_axis_aligned(lab: Lab) -> Case:
    """A container exactly along an axis and tilted off it: the fibers that change are the ones float64
    says move (a tilt of 1e-3 rad moves edges by a few hundredths of a pixel); a jump of the pattern
    would change far more. Rate: the worst excess of changed pixels over float64's."""
    p = Params({"scene.generator": "single", "fibers.rings": 5, "fibers.phi_step": 6.0, "fibers.fiber_radius": 0.03})
    size = (64, 64) if lab.quick else (96, 96)
    tilts = (1e-7, 1e-5) if lab.quick else (1e-7, 1e-6, 1e-5, 1e-4, 1e-3)
    worst, disagree, details, images, frame_jump = 0.0, 0.0, {}, [], 0.0
    for name, a in AXES.items():
        axis = np.array(a, np.float64)
        x0 = orthonormal_x(axis)[0]
        side = _unit(np.cross(axis, x0))

        def render(d):
            scene = Scene.from_polylines([np.array([-2 * d, 2 * d])], 1.0)
            lab.show(scene)
            cam = Camera(9.0 * side + 0.3 * d, np.zeros(3), 35.0, 0.5, 30.0, up=d)
            return lab.render(p, cam, size), reference_ids(scene, p, cam, size)[0]

        base, ref0 = render(axis)
        for tilt in tilts:
            for k in range(3):
                if abs(axis[k]) == 1:
                    continue
                d = axis.copy()
                d[k] += tilt
                d = _unit(d)
                frame_jump = max(frame_jump, float(np.linalg.norm(orthonormal_x(d)[0] - x0)) / tilt)
                f, ref = render(d)
                shown = base.hit | f.hit | (ref0[..., 0] > 0) | (ref[..., 0] > 0)
                moved = np.any(f.ids[..., :3] != base.ids[..., :3], -1)
                ref_moved = np.any(ref != ref0, -1)
                excess = float((moved & shown).sum() - (ref_moved & shown).sum()) / max(1, shown.sum())
                wrong = float((np.any(ref != ids3(f.ids), -1) & shown).sum()) / max(1, shown.sum())
                details[f"{name} tilt {tilt:g} along {'xyz'[k]}"] = {"changed": float(moved[shown].mean()),
                                                                     "float64_changed": float(ref_moved[shown].mean()),
                                                                     "differs_from_float64": wrong}
                disagree = max(disagree, wrong)
                if excess > worst or not images:
                    worst = max(worst, excess)
                    images = [(f"7: {name} tilted {tilt:g} (magenta: changed)", mark(id_image(f.ids), moved))]
    # the frame field's one singular direction: how far a 1e-7 tilt turns the frame at 1e-3 rad from it,
    # and across the circle where the basis used to switch to a fixed vector (a flip of up to 180 degrees)
    s = SINGULAR_AXIS
    p_ = _unit(np.cross(s, [1.0, 0, 0]))
    q_ = np.cross(s, p_)

    def around(theta, phi):
        return math.cos(theta) * s + math.sin(theta) * (math.cos(phi) * p_ + math.sin(phi) * q_)

    edge = math.acos(1.0 - 1e-6)
    singular_jump = max(float(np.linalg.norm(orthonormal_x(around(edge - 1e-8, f))[0]
                                             - orthonormal_x(around(edge + 1e-8, f))[0]))
                        for f in np.linspace(0, 2 * math.pi, 64, endpoint=False))
    return Case(7, "axis along +-X, +-Y, +-Z and 1e-7 rad off", worst < 5e-3 and disagree < 5e-3 and frame_jump < 10,
                max(worst, 0.0), "pixels whose fiber changes when the axis tilts, beyond those float64 changes "
                "(worst axis and tilt)", "< 0.5%, and < 0.5% differ from float64",
                f"at most {_pct(disagree)} of hit pixels differ from float64; frame change / tilt at most "
                f"{frame_jump:.2g} near the axes (smooth); about the frame field's one singular direction "
                f"{np.round(s, 3).tolist()} the frame turns by 2x the azimuth, and across 1.4e-3 rad from it "
                f"(where it once switched) it changes by {singular_jump:.2g} (see docs/limits.md)",
                {"tilts": details, "frame_lipschitz": frame_jump, "singular_jump": singular_jump}, images)


# ---------------------------------------------------------------------------------------------------
# 8. bends
# ---------------------------------------------------------------------------------------------------
def case_bends(lab: Lab) -> Case:
    size = (96, 72) if lab.quick else (160, 120)
    p = Params({"fibers.rings": 10, "fibers.phi_step": 2.0, "fibers.fiber_radius": 0.05, "fibers.length_jitter": 0.0})
    views = [[0, -8, 0.5], [6, -5, 3], [0.5, 0.2, 9], [8, 0.1, 2.5]]
    if lab.quick:
        views = views[:3]
    wrong_total = shown_total = seams = brute_diff = holes = 0
    details, images = {}, []
    for bend in (0.0, 1.0, 30.0, 90.0, 179.0):
        g = guide_polyline([0, 0, 0], [0, 0, 1], 4.0, 2, bend, [1.0, 0, 0])
        scene = Scene.from_polylines([g], 0.5)
        lab.show(scene)
        lo, hi = scene.bounds()
        centre = 0.5 * (lo + hi)
        s0 = reference.segment(scene.segments[0])
        joint = scene.origin + s0.p0 + s0.h * s0.ez
        n_joint = np.stack([s0.ex, s0.ey, s0.ez]).T @ s0.n1
        for view in views:
            cam = Camera(centre + np.array(view, float), centre, 40, 0.5, 40)
            f = lab.render(p, cam, size)
            b = lab.render(p, cam, size, "brute")
            ref, hits = reference_ids(scene, p, cam, size)
            wrong, shown = id_disagreement(ref, f.ids)
            wrong_total += int(wrong.sum())
            shown_total += int(shown.sum())
            holes += int(((ref[..., 0] > 0) & ~f.hit).sum())
            brute_diff += int(np.any(f.ids[..., :3] != b.ids[..., :3], -1).sum())
            # a seam: the visible surface is a fiber's cut section lying on the joint plane
            ro, rd = cam.rays(*size)
            t = f.geom[..., 3].reshape(-1).astype(np.float64)
            pts = ro + t[:, None] * rd
            on_joint = np.abs((pts - joint) @ n_joint) < 1e-3 * 0.5
            cut = (f.geom[..., :3].reshape(-1, 3).astype(np.float64) * -rd).sum(1) > 0.9999
            seam = (on_joint & cut).reshape(size[1], size[0]) & f.hit
            seams += int(seam.sum())
            details[f"bend {bend:g} view {view}"] = {"wrong": int(wrong.sum()), "seam": int(seam.sum())}
            if bend == 179.0 and view == views[1]:
                images.append((f"8: bend {bend:g}", mark(id_image(f.ids), wrong | seam)))
    rate = (wrong_total + seams) / max(1, shown_total)
    return Case(8, "bends of 0, 1, 30, 90, 179 degrees", rate < 1e-3 and brute_diff == 0 and holes == 0, rate,
                "hit pixels that differ from float64 or show a seam at the joint", "< 0.1%, no hole, exact == brute",
                f"{holes} holes, {seams} seam pixels (a fiber's cut face on the joint plane), {brute_diff} pixels "
                f"exact != brute, {wrong_total} of {shown_total} differ from float64", details, images)


# ---------------------------------------------------------------------------------------------------
# 9. jitter at and above its bound
# ---------------------------------------------------------------------------------------------------
def slot_overflow(p: Params) -> tuple[float, float, bool]:
    """Fiber centres as the shader computes them (float32) at the layout of ``p``: the largest excursion of
    a centre past the offset that keeps its disc in its angular slot (radians), the largest excursion of a
    disc past its ring's annulus (unit space), and whether each ring's centres stay in index order."""
    lay = ring_layout(p)
    f32 = np.float32
    worst_a = worst_r = 0.0
    ordered = True
    for i in range(lay.rings):
        j = np.arange(lay.n[i])
        ur = fiber_randoms(lay, 0, np.full_like(j, i), j, CH_RADIAL).astype(f32)
        ua = fiber_randoms(lay, 0, np.full_like(j, i), j, CH_ANGULAR).astype(f32)
        radius = (f32(lay.rho[i]) + (f32(2) * ur - f32(1)) * f32(lay.max_dr[i])).astype(np.float64)
        angle = (f32(lay.rot[i]) + j.astype(f32) * f32(lay.dphi[i])
                 + (f32(2) * ua - f32(1)) * f32(lay.max_dphi[i])).astype(np.float64)
        # the most a centre may move and keep its disc (half-angle seen from the axis) inside the slot
        half = np.arcsin(np.minimum(1.0, lay.fiber_radius / np.maximum(radius, 1e-300)))
        allowed = np.maximum(0.0, 0.5 * lay.dphi[i] - half)
        if lay.n[i] > 1:
            worst_a = max(worst_a, float(np.max(np.abs(angle - (lay.rot[i] + j * lay.dphi[i])) - allowed)))
            ordered &= bool(np.all(np.diff(angle) >= -1e-6))
        lo, hi = 1.0 - (i + 1.0) / lay.rings, 1.0 - i / lay.rings
        worst_r = max(worst_r, float(np.max(np.maximum(lo - (radius - lay.fiber_radius),
                                                       (radius + lay.fiber_radius) - hi))))
    return worst_a, worst_r, ordered


def case_jitter(lab: Lab) -> Case:
    problems, details = [], {}
    worst_a = worst_r = -1.0
    layouts = [(K, step, frac) for K in (1, 8, 64) for step in (0.01, 1.0, 30.0, 180.0) for frac in (1e-3, 0.5, 1.0)]
    if lab.quick:
        layouts = [L for L in layouts if not (L[0] == 64 and L[1] == 0.01)] + [(64, 0.01, 1.0)]
    for K, step, frac in layouts:
        p = Params({"fibers.rings": K, "fibers.phi_step": step, "fibers.fiber_radius": max_fiber_radius(K) * frac,
                    "fibers.radial_jitter": 1.0, "fibers.angular_jitter": 1.0})
        a, r, ordered = slot_overflow(p)
        worst_a, worst_r = max(worst_a, a), max(worst_r, r)
        if not ordered:
            problems.append(f"order lost: rings {K}, phi_step {step}, radius {frac:g} of the largest")
    if worst_a > 2e-6 or worst_r > 1e-6:      # a tenth of EPS_ANGLE, the traversal's angular slack
        problems.append(f"a fiber leaves its slot by {worst_a:.2g} rad / {worst_r:.2g} radially")
    # the GPU at full jitter: exact == brute, agreement with float64
    size = (96, 72) if lab.quick else (160, 120)
    p = Params({"scene.generator": "single", "scene.radius": 1.0, "scene.length": 3.0, "fibers.rings": 8,
                "fibers.phi_step": 2.0, "fibers.fiber_radius": max_fiber_radius(8), "fibers.radial_jitter": 1.0,
                "fibers.angular_jitter": 1.0})
    scene = build_scene(p)
    lab.show(scene)
    cam = Camera([3.0, -2.0, 2.8], [0, 0, 1.5], 40, 0.5, 20)
    e = lab.render(p, cam, size)
    b = lab.render(p, cam, size, "brute")
    ref, _ = reference_ids(scene, p, cam, size)
    differ = int(np.any(e.ids[..., :3] != b.ids[..., :3], -1).sum())
    wrong, shown = id_disagreement(ref, e.ids)
    disagree = float(wrong.sum() / max(1, shown.sum()))
    if differ or disagree > 1e-3:
        problems.append(f"full jitter on the GPU: {differ} px exact != brute, {_pct(disagree)} differ from float64")
    # just above the bound: rejected, with a message that names key, value and range
    messages = {}
    for key, value in (("fibers.radial_jitter", math.nextafter(1.0, 2.0)), ("fibers.angular_jitter", 1.0 + 1e-9),
                       ("fibers.fiber_radius", max_fiber_radius(8) * (1 + 1e-9))):
        try:
            Params({"fibers.rings": 8, key: value})
            problems.append(f"{key} = {value!r} was accepted")
        except ParamError as err:
            messages[key] = str(err)
            if key not in str(err) or "0.0625" not in str(err) and "[0, 1]" not in str(err):
                problems.append(f"unclear message for {key}: {err}")
    details.update({"slot_overflow_rel": worst_a, "annulus_overflow": worst_r, "gpu_differ": differ,
                    "gpu_float64_disagree": disagree, "messages": messages})
    return Case(9, "jitter at its maximum and just above", not problems, max(0.0, worst_a),
                "largest excursion (rad) of a float32 fiber centre past the offset that keeps it in its slot",
                "< 2e-6 rad (EPS_ANGLE / 10), order kept; above the bound: rejected",
                f"{len(layouts)} layouts at full jitter keep index order; GPU exact == brute ({differ} px), "
                f"{_pct(disagree)} differ from float64; above the bound: " + " | ".join(messages.values())
                + ("" if not problems else " PROBLEMS: " + "; ".join(problems)),
                details, [("9: full jitter, thickest fibers", id_image(e.ids))])


# ---------------------------------------------------------------------------------------------------
# 10. camera inside, extreme near and far planes
# ---------------------------------------------------------------------------------------------------
def case_inside(lab: Lab) -> Case:
    size = (64, 48) if lab.quick else (128, 96)
    p = Params({"fibers.rings": 5, "fibers.phi_step": 10.0, "fibers.fiber_radius": 0.02, "fibers.length_jitter": 0.2})
    axis = _unit([0.3, -0.5, 0.8])
    scene = Scene.from_polylines([np.array([-1.5 * axis, 0 * axis, 1.5 * axis])], 1.0)
    perp = _unit(np.cross(axis, [1.0, 0, 0]))
    spots = [("inside, along the axis", 0.2 * axis + 0.3 * perp, 1.5 * axis),
             ("inside, across", -0.5 * axis + 0.4 * perp, -0.5 * axis - perp),
             ("inside, at the joint, backwards", 0.0 * axis + 0.1 * perp, -1.5 * axis),
             ("outside", 4 * perp + axis, np.zeros(3))]
    planes = [(1e-4, 1e6), (1e-4, 10.0), (0.01, 1e6)] + ([] if lab.quick else [(1e-6, 1e9)])
    bad = shown_total = nonfinite = 0
    details, images = {}, []
    lab.show(scene)
    for (name, pos, target), (near, far) in itertools.product(spots, planes):
        cam = Camera(pos, target, 70, near, far, up=perp)
        f = lab.render(p, cam, size)
        ref, _ = reference_ids(scene, p, cam, size)
        wrong, shown = id_disagreement(ref, f.ids)
        bad += int(wrong.sum())
        shown_total += int(shown.sum())
        nonfinite += f.nonfinite()
        details[f"{name} near {near:g} far {far:g}"] = int(wrong.sum())
        if near == 1e-4 and far == 1e6 and name.startswith("inside, along") and not images:
            images.append((f"10: {name}, near 1e-4, far 1e6", mark(id_image(f.ids), wrong)))
    # many containers: the depth test across containers with near 1e-4, far 1e6 against tight planes
    carpet = Params({"scene.count": 12, "scene.segments": 3, "scene.bend": 40.0})
    cs = build_scene(carpet)
    lab.show(cs)
    base = Camera.from_params(carpet, cs, size[0] / size[1])
    tight = lab.render(carpet, base, size)
    wide = lab.render(carpet, Camera(base.position, base.target, base.fov, 1e-4, 1e6), size)
    depth_order = float(np.any(tight.ids[..., :3] != wide.ids[..., :3], -1).mean())
    rate = bad / max(1, shown_total)
    return Case(10, "camera inside a container; near 1e-4, far 1e6",
                rate < 1e-3 and nonfinite == 0 and depth_order < 1e-3,
                rate, "hit pixels whose fiber differs from float64", "< 0.1%, no NaN",
                f"{nonfinite} non-finite pixels; a carpet with near 1e-4 / far 1e6 names another fiber than with "
                f"tight planes in {_pct(depth_order)} of pixels (logarithmic depth)",
                {"views": details, "depth_order": depth_order}, images)


# ---------------------------------------------------------------------------------------------------
# 11. temporal stability and the thesis hash
# ---------------------------------------------------------------------------------------------------
ATTRIBUTE_FRAG = """#version 450 core
// Per-fiber attributes as the container shader computes them, one fiber per pixel.
#include "fibers/layout.glsl"
uniform int uGuide;
uniform int uWidth;
uniform int uFirst[MAX_RINGS + 1];
layout(location = 0) out vec4 outAttr;   // centre x, centre y, length (vEnd), tint random
void main() {
    int k = int(gl_FragCoord.y) * uWidth + int(gl_FragCoord.x);
    int ring = 0;
    for (int i = 0; i < uRings; i++) if (k >= uFirst[i + 1]) ring = i + 1;
    if (ring >= uRings) { outAttr = vec4(-1.0); return; }
    int j = k - uFirst[ring];
    vec2 c;
    float vEnd;
    fiber_center(uint(uGuide), ring, j, c, vEnd);
    outAttr = vec4(c, vEnd, key_random(fiber_key(uSeed, uint(uGuide), uint(ring), uint(j)), CH_TINT));
}
"""
ATTRIBUTE_VERT = "#version 450 core\nvoid main() { vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2); " \
                 "gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0); }\n"


def gpu_fiber_attributes(ctx: moderngl.Context, p: Params, guide: int) -> np.ndarray:
    """(fibers, 4) float32 from the shader's own layout code: centre x, y, vEnd, tint random."""
    from ..gl.shaders import ProgramCache, glsl_root

    lay = ring_layout(p)
    total = lay.fibers_per_container
    width = 256
    height = (total + width - 1) // width
    tmp = Path(tempfile.mkdtemp())
    try:
        shutil.copytree(glsl_root(), tmp / "glsl")
        (tmp / "glsl" / "extremes_attr.frag").write_text(ATTRIBUTE_FRAG)
        (tmp / "glsl" / "extremes_attr.vert").write_text(ATTRIBUTE_VERT)
        prog = ProgramCache(tmp / "glsl").get(ctx, "extremes_attr.vert", "extremes_attr.frag",
                                              {"MAX_RINGS": MAX_RINGS, "HASH_THESIS": int(lay.thesis_hash)})
    finally:
        shutil.rmtree(tmp)
    K = lay.rings
    first = np.full(MAX_RINGS + 1, np.iinfo(np.int32).max, np.int32)
    first[:K + 1] = np.concatenate([lay.first, [total]])
    for name, arr in (*ring_uniforms(lay).items(), ("uFirst", first)):
        if name in prog:
            prog[name].write(arr.tobytes())
    for name, value in (("uRings", K), ("uLengthJitter", lay.length_jitter), ("uSeed", lay.seed),
                        ("uGuide", guide), ("uWidth", width)):
        if name in prog:
            prog[name].value = value
    tex = ctx.texture((width, height), 4, dtype="f4")
    fbo = ctx.framebuffer([tex])
    fbo.use()
    ctx.viewport = (0, 0, width, height)
    ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE | moderngl.BLEND)
    vao = ctx.vertex_array(prog, [])
    vao.render(moderngl.TRIANGLES, vertices=3)
    out = np.frombuffer(tex.read(), np.float32).reshape(-1, 4)[:total].copy()
    vao.release()
    return out


def float32_attributes(p: Params, guide: int) -> np.ndarray:
    """The same attributes emulated in numpy float32 (integer hash: bit-exact 24-bit randoms)."""
    lay = ring_layout(p)
    ring, j, *_ = all_fibers(lay, guide)
    f32 = np.float32
    u = [fiber_randoms(lay, guide, ring, j, ch).astype(f32)
         for ch in (CH_RADIAL, CH_ANGULAR, CH_LENGTH, CH_TINT)]
    v_end = f32(1) - f32(lay.length_jitter) * u[2]
    return np.stack([v_end, u[3]], 1)


def case_temporal(lab: Lab) -> Case:
    frames_n = 100
    size = (48, 48) if lab.quick else (96, 96)
    details, images, problems = {}, [], []
    scene = Scene.from_polylines([np.array([[0, 0, 0], [0.2, 0.1, 1.0], [0.5, 0.1, 2.0]])], 1.0)
    cam = Camera([2.6, -1.2, 1.4], [0.2, 0.05, 1.0], 40, 0.5, 20)
    for hash_name in ("integer", "thesis"):
        p = Params({"fibers.rings": 4, "fibers.phi_step": 12.0, "fibers.fiber_radius": 0.06,
                    "fibers.length_jitter": 0.4, "fibers.hash": hash_name})
        lab.show(scene)
        ids, colors, refs = [], [], []
        for k in range(frames_n):
            offset = (k * 1e-3, 0.0)
            f = lab.render(p, cam, size, offset=offset)
            ids.append(ids3(f.ids))
            colors.append(f.color)
            refs.append(reference_ids(scene, p, cam, size, offset)[0])
        ids, colors, refs = np.stack(ids), np.stack(colors), np.stack(refs)
        changed = np.any(ids[1:] != ids[:-1], -1)                       # (frames - 1, H, W)
        ref_changed = np.any(refs[1:] != refs[:-1], -1)
        # flicker: a pixel that leaves a fiber and comes back to it while the camera moves one way; the
        # integer hash's fibers sit where float64 puts them, so it must also change no more than float64
        back = np.zeros(changed.shape[1:], bool)
        for k in range(2, frames_n):
            back |= np.any(ids[k] != ids[k - 1], -1) & np.any(ids[:k - 1] == ids[k][None], axis=0).all(-1)
        flicker = back | ((changed.sum(0) > ref_changed.sum(0)) if hash_name == "integer" else False)
        same = ~changed & (ids[1:, ..., 0] > 0)
        dcol = np.abs(colors[1:, ..., :3] - colors[:-1, ..., :3]).max(-1)
        steps = np.quantile(dcol[same], [0.5, 0.999, 1.0]) if same.any() else np.zeros(3)
        # the attributes the shader gives each visible fiber, from its own code, against float32 numpy
        seen = np.unique(ids[ids[..., 0] > 0].reshape(-1, 3), axis=0)
        lay = ring_layout(p)
        attr_ok = True
        for g in np.unique(seen[:, 0]):
            gpu = gpu_fiber_attributes(lab.ctx, p, int(g) - 1)
            want = float32_attributes(p, int(g) - 1)
            rows = seen[seen[:, 0] == g]
            flat = lay.first[rows[:, 1]] + rows[:, 2]
            if hash_name == "integer":
                attr_ok &= bool((gpu[flat, 2:4] == want[flat]).all())
        details[hash_name] = {"pixels_changing_id": float(changed.any(0).mean()),
                              "float64_pixels_changing_id": float(ref_changed.any(0).mean()),
                              "flicker_pixels": int(flicker.sum()),
                              "colour_step_same_fiber_median_999_max": [float(x) for x in steps],
                              "fibers_seen": int(len(seen)),
                              "attributes_bit_exact": attr_ok}
        if flicker.any():
            problems.append(f"{hash_name}: {int(flicker.sum())} pixels flicker")
        if hash_name == "integer" and not attr_ok:
            problems.append("integer hash: the shader's fiber attributes differ from their float32 twin")
        if hash_name == "integer":
            images.append(("11: 100 frames, 1e-3 px apart (magenta: id changed)", mark(id_image(ids[0]),
                                                                                     changed.any(0))))
    # the thesis hash: the same fibers' random numbers in float32 (the shader) against float64
    flips = {}
    for name, values in (("default 10 rings x 1 deg", {}),
                         ("64 rings x 0.01 deg", {"fibers.rings": 64, "fibers.phi_step": 0.01,
                                                  "fibers.fiber_radius": 0.005})):
        lay = ring_layout(Params({**values, "fibers.hash": "thesis"}))
        ring = np.repeat(np.arange(lay.rings), lay.n)
        j = np.arange(lay.fibers_per_container) - np.repeat(lay.first, lay.n)
        slot = np.degrees(lay.rot[ring] + j * lay.dphi[ring])
        diffs = []
        for ch in (CH_RADIAL, CH_ANGULAR, CH_LENGTH):
            d = np.abs(thesis_random(slot, ring, ch, np.float32) - thesis_random(slot, ring, ch, np.float64))
            diffs.append(d)
        d = np.max(diffs, 0)
        flips[name] = {"gt_1e-3": float((d > 1e-3).mean()), "gt_1e-2": float((d > 1e-2).mean()),
                       "wrap_gt_0.5": float((d > 0.5).mean())}
    details["thesis_flips"] = flips
    rate = flips["default 10 rings x 1 deg"]["gt_1e-2"]
    integer = details["integer"]
    return Case(11, "temporal stability; thesis-hash flips", not problems, rate,
                "fibers whose thesis-hash numbers differ float32 vs float64 by > 0.01 (default layout)",
                "integer hash: no flicker, attributes bit-exact",
                f"integer hash over 100 frames 1e-3 px apart: {integer['flicker_pixels']} pixels change fiber more "
                f"often than in float64; {_pct(integer['pixels_changing_id'])} of pixels change fiber (float64: "
                f"{_pct(integer['float64_pixels_changing_id'])}: edges crossing 0.1 px); colour step per frame on an "
                "unchanged fiber: median {:.2g}, 99.9% {:.2g}, max {:.2g} (a hit crossing a joint or a tip, where "
                "piecewise-straight fibers crease); attributes bit-exact: ".format(
                    *integer["colour_step_same_fiber_median_999_max"])
                + f"{integer['attributes_bit_exact']}; thesis hash float32 vs float64: "
                + "; ".join(f"{k}: {_pct(v['gt_1e-3'])} > 1e-3, {_pct(v['gt_1e-2'])} > 0.01, "
                            f"{_pct(v['wrap_gt_0.5'])} wrap" for k, v in flips.items())
                + ("" if not problems else " PROBLEMS: " + "; ".join(problems)), details, images)


# ---------------------------------------------------------------------------------------------------
# 12. slider ends and pairwise extremes
# ---------------------------------------------------------------------------------------------------
SKIP_KEYS = {"scene.groom_file", "scene.groom_up", "scene.groom_scale", "scene.groom_cluster"}
HEAVY_ENDS = {("scene.count", 200_000), ("fibers.phi_step", 0.01)}


def slider_end_values(quick: bool) -> list[tuple[str, object, dict]]:
    """(key, value, the other parameters it needs): every numeric slider at both ends, every choice."""
    out = []
    for prm in SPEC:
        if prm.key in SKIP_KEYS:
            continue
        if prm.kind in (int, float):
            values = [prm.lo, prm.hi]
        elif prm.kind is tuple:
            values = [(prm.lo,) * 3, (prm.hi,) * 3]
        elif prm.choices:
            values = [c for c in prm.choices if c != "groom"]
        else:
            continue
        for v in values:
            extra = {}
            if prm.key == "fibers.rings":
                extra = {"fibers.fiber_radius": max_fiber_radius(int(v))}
            if prm.key == "fibers.fiber_radius" and v == prm.hi:
                extra = {"fibers.rings": 1}
            if prm.key == "quality.msaa" and v == prm.hi:
                v = 4                                   # llvmpipe offers 4 samples; 8 is refused with a message
            if quick and (prm.key, v) in HEAVY_ENDS:
                continue
            out.append((prm.key, v, extra))
    return out


FACTORS = {"fibers.rings": (1, 64), "fibers.phi_step": (0.01, 180.0), "jitter": (0.0, 1.0),
           "shape.curl_amplitude": (0.0, 0.5), "shape.twist": (-8.0, 8.0)}


def pairwise_rows() -> list[tuple[int, ...]]:
    """A small covering array: every pair of extremes of the five factors in some row; the costly pair
    (64 rings, 0.01 degrees) in as few rows as possible."""
    keys = list(FACTORS)
    rows = list(itertools.product((0, 1), repeat=len(keys)))
    need = {(a, b, x, y) for a, b in itertools.combinations(range(len(keys)), 2) for x in (0, 1) for y in (0, 1)}
    chosen = []
    while need:
        def gain(r):
            covered = sum((a, b, r[a], r[b]) in need for a, b in itertools.combinations(range(len(keys)), 2))
            return 10 * covered - (5 if r[0] == 1 and r[1] == 0 else 0) if covered else -100
        best = max(rows, key=gain)
        chosen.append(best)
        need -= {(a, b, best[a], best[b]) for a, b in itertools.combinations(range(len(keys)), 2)}
    return chosen


def pairwise_params(row: tuple[int, ...]) -> dict:
    values = {}
    for (key, ends), bit in zip(FACTORS.items(), row):
        v = ends[bit]
        if key == "jitter":
            values["fibers.radial_jitter"] = values["fibers.angular_jitter"] = v
        else:
            values[key] = v
    values["fibers.fiber_radius"] = min(0.01, max_fiber_radius(values["fibers.rings"]))
    return values


def case_grid(lab: Lab) -> Case:
    size = (32, 24) if lab.quick else (48, 32)
    problems, details, images = [], {}, []
    checked = 0
    for key, value, extra in slider_end_values(lab.quick):
        t = time.perf_counter()
        values = {"scene.count": 4, key: value, **extra}
        try:
            p = Params(values)
        except ParamError as err:
            problems.append(f"{key} = {value!r} rejected: {err}")
            continue
        scene = build_scene(p)
        lab.show(scene)
        cam = Camera.from_params(p, scene, size[0] / size[1])
        try:
            color = lab.r.render(p, cam, size, outputs=("color",)).color   # the real path: AA, MSAA
        except ParamError as err:
            details[f"{key}={value}"] = f"refused: {err}"
            continue
        differ, _, runout, finite, frames = check_exact_equals_brute(lab, p, cam, size, ("exact", "brute"))
        checked += 1
        details[f"{key}={value!r}"] = {"differ": int(differ.sum()), "runout": runout, "finite": finite}
        lab.log(f"{key} = {value!r}: {time.perf_counter() - t:.1f} s")
        if differ.any() or runout or not finite or color is None:
            problems.append(f"{key} = {value!r}: {int(differ.sum())} px exact != brute, {runout} run-outs, "
                            f"finite {finite}")
            images.append((f"12: {key} = {value!r}", mark(id_image(frames['exact'].ids), differ)))
    rows = pairwise_rows()
    single = Scene.from_polylines([np.array([[0, 0, 0], [0, 0, 2.0]])], 1.0)
    cam = Camera([2.2, 0.6, 1.8], [0, 0, 1.0], 40, 0.5, 20)
    for row in rows:
        t = time.perf_counter()
        values = pairwise_params(row)
        heavy = values["fibers.rings"] == 64 and values["fibers.phi_step"] == 0.01
        if heavy and lab.quick:
            details[f"pairwise {values}"] = "slow: full run only"
            continue
        p = Params(values)
        lab.show(single)
        # brute force over 36,000 curved fibers a pixel costs ~0.1 s on llvmpipe: keep those images tiny
        small = (4, 4) if heavy else (8, 8) if values["fibers.phi_step"] == 0.01 else size
        differ, _, runout, finite, frames = check_exact_equals_brute(lab, p, cam, small, ("exact", "brute"))
        lab.log(f"pairwise {row}: {time.perf_counter() - t:.1f} s, {frames['exact'].draws} exact draws")
        checked += 1
        details[f"pairwise {values}"] = {"differ": int(differ.sum()), "runout": runout, "finite": finite,
                                         "draws": frames["exact"].draws}
        if differ.any() or runout or not finite:
            problems.append(f"pairwise {values}: {int(differ.sum())} px differ, {runout} run-outs, finite {finite}")
    return Case(12, "slider ends; pairwise extremes of rings, phi_step, jitter, curl, twist", not problems,
                len(problems) / max(1, checked), "configurations with a non-finite value, exact != brute or a run-out",
                "none", f"{checked} configurations ({len(rows)} pairwise rows)"
                + ("" if not problems else " PROBLEMS: " + "; ".join(problems[:5])), details, images[:2])


# ---------------------------------------------------------------------------------------------------
# Report
# ---------------------------------------------------------------------------------------------------
CASES: dict[int, Callable[[Lab], Case]] = {
    1: case_translation, 2: case_distance, 3: case_radius, 4: case_many_fibers, 5: case_grazing,
    6: case_axis_rays, 7: case_axis_aligned, 8: case_bends, 9: case_jitter, 10: case_inside,
    11: case_temporal, 12: case_grid,
}


def contact_sheet(cases: list[Case], path: Path, cell: int = 160) -> None:
    from PIL import Image, ImageDraw

    tiles = [(c, caption, img) for c in cases for caption, img in c.images]
    if not tiles:
        return
    cols = 4
    rows = (len(tiles) + cols - 1) // cols
    sheet = Image.new("RGB", (cols * cell, rows * (cell + 28)), (24, 24, 28))
    draw = ImageDraw.Draw(sheet)
    for k, (case, caption, img) in enumerate(tiles):
        im = Image.fromarray(np.ascontiguousarray(img))
        scale = cell / max(im.size)
        im = im.resize((max(1, round(im.size[0] * scale)), max(1, round(im.size[1] * scale))), Image.NEAREST)
        x, y = (k % cols) * cell, (k // cols) * (cell + 28)
        sheet.paste(im, (x + (cell - im.size[0]) // 2, y))
        colour = (120, 220, 120) if case.passed else (255, 90, 90)
        draw.text((x + 3, y + cell + 2), caption[:30], fill=colour)
        draw.text((x + 3, y + cell + 14), caption[30:60], fill=colour)
    sheet.save(path)


def markdown(cases: list[Case], quick: bool, renderer: str) -> str:
    lines = [f"# vfiber bench extremes ({'quick' if quick else 'full'})", "",
             f"Renderer: {renderer}. Each case renders float outputs and holds them against the float64 "
             "reference or the same scene in a benign configuration (app/bench/extremes.py).", "",
             "| case | result | rate | what the rate counts | pass when | notes |", "|---|---|---|---|---|---|"]
    for c in cases:
        lines.append(f"| {c.number}. {c.title} | {'pass' if c.passed else '**FAIL**'} | {c.rate:.3g} | {c.measure} | "
                     f"{c.threshold} | {c.notes.replace('|', '/')} |")
    lines += ["", f"{sum(c.passed for c in cases)} of {len(cases)} cases pass; "
              f"{sum(c.seconds for c in cases):.0f} s in all.", ""]
    lines += ["See docs/limits.md for what still fails and the ranges the tool enforces.", ""]
    return "\n".join(lines)


def run_extremes(out_dir, quick: bool, cases: list[int] | None = None, ctx: moderngl.Context | None = None,
                 verbose: bool = False) -> list[dict]:
    """Run the cases (all by default), write extremes.md, extremes.json and extremes.png to ``out_dir``;
    return one row per case (number, title, passed, rate, measure, threshold, notes, details, seconds)."""
    from ..gl.context import create_headless

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    hc = None
    if ctx is None:
        hc = create_headless()
        ctx = hc.ctx
    try:
        lab = Lab(ctx, quick, verbose)
        results = []
        for number in cases or sorted(CASES):
            t = time.perf_counter()
            case = CASES[number](lab)
            case.seconds = time.perf_counter() - t
            results.append(case)
            print(f"  {case.number:2d}. {case.title:<60s} {'pass' if case.passed else 'FAIL'}  "
                  f"rate {case.rate:.3g}  ({case.seconds:.0f} s)", flush=True)
        lab.r.release_targets()
        renderer = ctx.info.get("GL_RENDERER", "?")
        (out / "extremes.md").write_text(markdown(results, quick, renderer))
        (out / "extremes.json").write_text(json.dumps({"cases": [c.row() for c in results]}, indent=2,
                                                      default=float))
        contact_sheet(results, out / "extremes.png")
        return [c.row() for c in results]
    finally:
        if hc is not None:
            hc.release()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="vfiber bench extremes", description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="the reduced set the tests run (a few minutes)")
    ap.add_argument("--out", type=Path, default=None, help="output folder (default out/bench-extremes)")
    ap.add_argument("--case", type=int, action="append", choices=sorted(CASES), help="run only this case "
                    "(repeatable)")
    ap.add_argument("-v", "--verbose", action="store_true", help="print each configuration's time")
    args = ap.parse_args(argv)
    out = args.out or Path("out") / ("bench-extremes-quick" if args.quick else "bench-extremes")
    rows = run_extremes(out, args.quick, args.case, verbose=args.verbose)
    print(f"wrote {out / 'extremes.md'}, {out / 'extremes.png'}")
    return 0 if all(r["passed"] for r in rows) else 1


if __name__ == "__main__":
    raise SystemExit(main())
