"""The benchmark suites: what each measures, on which scenes, at which sizes.

Every suite lists its configurations for three levels -- ``full`` (what docs/benchmarks.md publishes),
``quick`` (CI and newcomers, the whole set under two minutes on a 2-core llvmpipe) and ``smoke`` (one tiny
configuration per suite, for the tests) -- and turns one configuration into table rows. A suite marked
``isolate`` runs every configuration in a fresh process (``app.bench.worker``) so that a peak resident
set size belongs to that configuration alone.

Scenes are built here from the same parameters, generators and ``Scene.from_polylines`` as everything
else; nothing here reaches into a renderer's internals.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .. import reference          # the float64 judge; the model itself comes from app.fibers
from ..fibers import ring_layout
from ..params import Params
from ..render.camera import Camera
from ..render.explicit import DEFAULT_BUDGET_BYTES, ExplicitBudgetError, ExplicitRenderer, compare_frames
from ..render.renderer import Frame, Renderer
from ..scene.containers import Scene
from ..scene.generators import build_scene, guide_polyline
from . import grooms, looks
from .scenes import overlapping_scene
from .timing import UNFILTERED, current_rss_bytes, peak_rss_bytes, time_frames, unfiltered

Row = dict[str, Any]
LEVELS = ("smoke", "quick", "full")


@dataclass
class Env:
    """What a configuration runs on: one context, one virtual renderer, an explicit one made on demand."""
    ctx: Any
    reps: int = 10
    warmup: int = 2
    budget_bytes: int = DEFAULT_BUDGET_BYTES
    level: str = "full"
    out: str | None = None                        # the run's output folder: suites with pictures write there
    _virtual: Renderer | None = None
    _explicit: ExplicitRenderer | None = None

    @property
    def virtual(self) -> Renderer:
        if self._virtual is None:
            self._virtual = Renderer(self.ctx)
        return self._virtual

    @property
    def explicit(self) -> ExplicitRenderer:
        if self._explicit is None:
            self._explicit = ExplicitRenderer(self.ctx, budget_bytes=self.budget_bytes)
        return self._explicit

    def drop_explicit(self) -> None:
        """Free the explicit fibers so that one configuration's buffers do not sit under the next."""
        if self._explicit is not None:
            self._explicit.release()
            self._explicit.release_targets()
            self._explicit = None

    # Frames are timed with outputs=("draw",): clear, draw, ctx.finish(), nothing read back, so that a
    # method's time is its rendering and not numpy's compositing or the read-back (the same for both).
    def time_virtual(self, p: Params, cam: Camera, size, mode: str, reps: int | None = None):
        r = self.virtual
        return time_frames(lambda: r.render(p, cam, size, outputs=("draw",), mode=mode),
                           warmup=self.warmup, reps=reps or self.reps, sync=self.ctx.finish)

    def time_explicit(self, p: Params, cam: Camera, size, reps: int | None = None):
        e = self.explicit
        return time_frames(lambda: e.render(p, cam, size, outputs=("draw",)),
                           warmup=self.warmup, reps=reps or self.reps, sync=self.ctx.finish)

    def cost(self, p: Params, cam: Camera, size, mode: str) -> dict[str, float]:
        """Work per covered pixel from the virtual renderer's cost pass."""
        f = self.virtual.render(p, cam, size, outputs=("ids", "cost"), mode=mode)
        covered = int(f.hit.sum())
        return {"covered": covered / (size[0] * size[1]),
                "tests_per_px": float(f.cost[..., 0].sum() / max(1, covered)),
                "iters_per_px": float(f.cost[..., 3].sum() / max(1, covered))}


@dataclass
class Suite:
    name: str
    title: str
    thesis: str                                   # which table/figure of the thesis it mirrors
    configs: Callable[[str], list[dict]]
    run: Callable[[Env, dict], list[Row]]
    isolate: bool = False
    columns: list[tuple[str, str]] = field(default_factory=list)   # (key, heading) for the Markdown table


def _size(level: str, full, quick, smoke=(64, 36)):
    return {"full": full, "quick": quick, "smoke": smoke}[level]


def _timing_row(prefix: str, t) -> Row:
    return {f"{prefix}ms": round(t.median_ms, 3), f"{prefix}cv": round(t.cv, 4), f"{prefix}reps": t.reps}


# --------------------------------------------------------------------------------------------------
# Layouts: how many fibers a container holds
# --------------------------------------------------------------------------------------------------
def layout_for(per_container: int, fiber_radius: float = 0.005) -> dict[str, Any]:
    """Rings and phi_step that give ``per_container`` fibers (exactly, when it divides): K = cube root of
    the count (1..64 rings), the rest spread evenly over the rings."""
    K = int(np.clip(round(per_container ** (1 / 3)), 1, 64))
    per_ring = max(1, round(per_container / K))
    return {"fibers.rings": K, "fibers.phi_step": 360.0 / per_ring,
            "fibers.fiber_radius": min(fiber_radius, 0.5 / K)}


# --------------------------------------------------------------------------------------------------
# memory: thesis Table 2, Figures 37-38
# --------------------------------------------------------------------------------------------------
MEMORY_CONTAINERS = 100


def memory_configs(level: str) -> list[dict]:
    if level == "smoke":
        totals, containers, size = [400], 4, (64, 36)
    elif level == "quick":
        totals, containers, size = [10**3, 10**4, 10**5, 10**8], 50, (160, 90)
    else:
        totals = [10**3, 3 * 10**3, 10**4, 3 * 10**4, 10**5, 3 * 10**5, 10**6, 3 * 10**6, 10**7, 3 * 10**7,
                  10**8]
        containers, size = MEMORY_CONTAINERS, (480, 270)
    out = []
    for total in totals:
        for method in ("virtual", "explicit"):
            cfg = {"fibers_target": total, "containers": containers, "method": method, "size": size}
            if method == "explicit" and level == "full" and total >= 10**7:
                # one explicit frame of 1e7 fibers takes 10-40 s here: 12 would take the full run past
                # thirty minutes, so these rows draw one frame (for the peak RSS and an idea of the time)
                cfg["frames"] = 1
            out.append(cfg)
    return out


def memory_scene(cfg: dict) -> tuple[Params, Scene, Camera]:
    per = max(1, round(cfg["fibers_target"] / cfg["containers"]))
    p = Params({"scene.generator": "carpet", "scene.count": cfg["containers"], **layout_for(per), **UNFILTERED})
    scene = build_scene(p)
    return p, scene, Camera.from_params(p, scene)


def memory_run(env: Env, cfg: dict) -> list[Row]:
    p, scene, cam = memory_scene(cfg)
    size = tuple(cfg["size"])
    lay = ring_layout(p)
    row: Row = {"method": cfg["method"], "fibers": lay.fibers_per_container * scene.n_guides,
                "containers": scene.n_segments, "fibers_per_container": lay.fibers_per_container,
                "rings": lay.rings, "width": size[0], "height": size[1], "rss_base": current_rss_bytes()}
    if cfg["method"] == "virtual":
        import time as _t
        t0 = _t.perf_counter()
        env.virtual.set_scene(scene)
        row["build_s"] = round(_t.perf_counter() - t0, 4)
        row["gpu_bytes"] = env.virtual.scene_gpu_bytes
        row.update(_timing_row("", env.time_virtual(p, cam, size, "exact")))
        row.update(_timing_row("fast_", env.time_virtual(p, cam, size, "fast")))
        row["rss_peak"] = peak_rss_bytes()
        row["status"] = "ok"
        return [row]
    try:
        stats = env.explicit.set_scene(scene, p)
    except ExplicitBudgetError as exc:
        row.update(status="refused", needed_bytes=exc.needed, note=str(exc).split(":")[0],
                   rss_peak=peak_rss_bytes())
        return [row]
    row["build_s"] = round(stats.seconds, 4)
    row["gpu_bytes"] = env.explicit.gpu_bytes
    if cfg.get("frames") == 1:
        t = time_frames(lambda: env.explicit.render(p, cam, size, outputs=("draw",)), warmup=0, reps=1,
                        sync=env.ctx.finish)
        row.update(_timing_row("", t), cv=None)
    else:
        row.update(_timing_row("", env.time_explicit(p, cam, size)))
    row["rss_peak"] = peak_rss_bytes()         # before the virtual frame drawn below for comparison
    row["status"] = "ok"
    fe = env.explicit.render(p, cam, size, outputs=("color", "ids"))
    env.virtual.set_scene(scene)
    fv = env.virtual.render(p, cam, size, outputs=("color", "ids"), mode="exact")
    row.update({k: round(v, 5) for k, v in compare_frames(fv, fe).items()})
    env.drop_explicit()
    return [row]


# --------------------------------------------------------------------------------------------------
# rings: thesis Table 3, Figure 41 (one container, rings x fibers per ring)
# --------------------------------------------------------------------------------------------------
THESIS_RINGS = (1, 5, 10, 20, 40)
THESIS_PER_RING = (2, 4, 10, 30, 45, 90, 180, 360)


def rings_configs(level: str) -> list[dict]:
    if level == "smoke":
        return [{"rings": 5, "per_ring": 10, "size": (64, 36)}]
    rings, per = (THESIS_RINGS, THESIS_PER_RING) if level == "full" else ((1, 10, 40), (2, 30, 360))
    size = _size(level, (480, 270), (128, 72))
    return [{"rings": k, "per_ring": m, "size": size} for k in rings for m in per]


def single_container(rings: int, per_ring: int, fiber_radius: float = 0.01) -> tuple[Params, Scene, Camera]:
    p = Params({"scene.generator": "single", "scene.radius": 1.0, "scene.length": 4.0,
                "fibers.rings": rings, "fibers.phi_step": 360.0 / per_ring,
                "fibers.fiber_radius": min(fiber_radius, 0.5 / rings), "camera.elevation": 10.0, **UNFILTERED})
    scene = build_scene(p)
    return p, scene, Camera.from_params(p, scene)


def rings_run(env: Env, cfg: dict) -> list[Row]:
    p, scene, cam = single_container(cfg["rings"], cfg["per_ring"])
    size = tuple(cfg["size"])
    env.virtual.set_scene(scene)
    base = {"rings": cfg["rings"], "per_ring": cfg["per_ring"],
            "fibers": ring_layout(p).fibers_per_container}
    rows = []
    for mode in ("fast", "exact"):
        r = dict(base, method=f"virtual-{mode}")
        r.update(_timing_row("", env.time_virtual(p, cam, size, mode)))
        r.update(env.cost(p, cam, size, mode))
        rows.append(r)
    env.explicit.set_scene(scene, p)
    r = dict(base, method="explicit")
    r.update(_timing_row("", env.time_explicit(p, cam, size)))
    rows.append(r)
    env.drop_explicit()
    return rows


# --------------------------------------------------------------------------------------------------
# containers: thesis Table 4 (overlapping containers, "empty" and "full")
# --------------------------------------------------------------------------------------------------
def containers_configs(level: str) -> list[dict]:
    if level == "smoke":
        return [{"n": 3, "fill": "full", "size": (64, 36)}]
    counts = (1, 2, 5, 10, 20, 50, 100, 200) if level == "full" else (1, 5, 25)
    size = _size(level, (480, 270), (128, 72))
    return [{"n": n, "fill": fill, "size": size} for fill in ("empty", "full") for n in counts]


def containers_run(env: Env, cfg: dict) -> list[Row]:
    per_ring = 2 if cfg["fill"] == "empty" else 360
    p, scene, cam = overlapping_scene(cfg["n"], per_ring)
    p = unfiltered(p)                   # the unfiltered traversal's figures (timing.UNFILTERED)
    size = tuple(cfg["size"])
    env.virtual.set_scene(scene)
    base = {"containers": cfg["n"], "fill": cfg["fill"], "fibers": cfg["n"] * 10 * per_ring}
    rows = []
    for mode in ("fast", "exact"):
        r = dict(base, method=f"virtual-{mode}")
        r.update(_timing_row("", env.time_virtual(p, cam, size, mode)))
        c = env.cost(p, cam, size, mode)
        f = env.virtual.render(p, cam, size, outputs=("cost",), mode=mode)
        r.update(c, fragments_per_px=float(f.cost[..., 2].sum() / (size[0] * size[1])))
        rows.append(r)
    env.explicit.set_scene(scene, p)
    r = dict(base, method="explicit")
    r.update(_timing_row("", env.time_explicit(p, cam, size)))
    rows.append(r)
    env.drop_explicit()
    return rows


# --------------------------------------------------------------------------------------------------
# accuracy: modes x shapes, against brute force and against the float64 reference
# --------------------------------------------------------------------------------------------------
SHAPES = {
    "straight": {},
    "curled": {"shape.curl_amplitude": 0.3, "shape.curl_frequency": 4.0},
    "twisted": {"shape.twist": 1.0},
}


def accuracy_configs(level: str) -> list[dict]:
    if level == "smoke":
        return [{"shape": "straight", "count": 3, "size": (48, 27), "ref_size": (24, 14)}]
    size, ref = _size(level, (160, 90), (64, 36)), _size(level, (96, 54), (32, 18))
    count = 12 if level == "full" else 4
    return [{"shape": s, "count": count, "size": size, "ref_size": ref} for s in SHAPES]


def accuracy_run(env: Env, cfg: dict) -> list[Row]:
    # thesis-like carpet: 10 rings x 360 fibers = 3,600 fibers per container
    p = Params({"scene.generator": "carpet", "scene.count": cfg["count"], **SHAPES[cfg["shape"]], **UNFILTERED})
    scene = build_scene(p)
    cam = Camera.from_params(p, scene)
    size, ref_size = tuple(cfg["size"]), tuple(cfg["ref_size"])
    r = env.virtual
    r.set_scene(scene)
    brute = r.render(p, cam, size, outputs=("ids",), mode="brute")
    lay = ring_layout(p)
    ro, rd = cam.rays(*ref_size)
    hits = reference.brute_nearest(scene, p, ro, rd, t_near=cam.near)
    ref_ids = np.stack([np.where(hits.hit, hits.guide + 1, 0), np.where(hits.hit, hits.ring, 0),
                        np.where(hits.hit, hits.fiber, 0)], -1).reshape(ref_size[1], ref_size[0], 3)
    rows = []
    for mode in ("fast", "exact", "brute"):
        row: Row = {"shape": cfg["shape"], "mode": mode, "fibers_per_container": lay.fibers_per_container,
                    "containers": scene.n_segments, "width": size[0], "height": size[1]}
        if mode == "brute" and env.level != "full":
            # brute force of curved fibers costs seconds a frame even here: the quick run times 3 frames
            row.update(_timing_row("", time_frames(lambda: r.render(p, cam, size, outputs=("draw",),
                                                                     mode=mode), warmup=0, reps=3,
                                                   sync=env.ctx.finish)))
        else:
            row.update(_timing_row("", env.time_virtual(p, cam, size, mode)))
        row.update(env.cost(p, cam, size, mode))
        f = brute if mode == "brute" else r.render(p, cam, size, outputs=("ids",), mode=mode)
        differ = np.any(_ids3(f) != _ids3(brute), -1)
        row["differ_brute_px"] = int(differ.sum())
        row["differ_brute_pct"] = round(100.0 * differ.mean(), 4)
        small = r.render(p, cam, ref_size, outputs=("ids",), mode=mode)
        mine = _ids3(small)
        either = (mine[..., 0] > 0) | (ref_ids[..., 0] > 0)
        bad = np.any(mine != ref_ids, -1) & either
        row["differ_ref_px"] = int(bad.sum())
        row["differ_ref_pct_of_hit"] = round(100.0 * bad.sum() / max(1, either.sum()), 4)
        rows.append(row)
    brute_tests = rows[2]["tests_per_px"]
    for row in rows:
        row["tests_vs_brute"] = round(brute_tests / max(row["tests_per_px"], 1e-9), 2)
    return rows


def _ids3(f: Frame) -> np.ndarray:
    ids = f.ids[..., :3].astype(np.int64)
    ids[ids[..., 0] == 0] = 0
    return ids


# --------------------------------------------------------------------------------------------------
# scaling: time against resolution, visible containers and rings; fit the exponents
# --------------------------------------------------------------------------------------------------
def grid_scene(n: int) -> tuple[Params, Scene, Camera]:
    """``n`` upright containers on a 16 x 9 grid, none hiding another, in a fixed camera frame sized for
    144 of them, so every container keeps the same footprint in pixels whatever ``n`` is."""
    p = Params({"scene.radius": 0.1, "fibers.phi_step": 3.0, **UNFILTERED})
    i = np.arange(n)
    roots = np.stack([np.zeros(n), (i % 16 - 7.5) * 0.45, (i // 16) * 0.6], 1)
    guides = [guide_polyline(r, [0, 0, 1], 0.5, 1, 0.0) for r in roots]
    scene = Scene.from_polylines(guides, 0.1, name="grid", origin=np.zeros(3))
    centre = np.array([0.0, 0.0, 9 * 0.6 / 2 - 0.05])
    cam = Camera(position=centre + [5.0, 0.0, 0.0], target=centre, fov=60.0, near=2.0, far=10.0)
    return p, scene, cam


def scaling_configs(level: str) -> list[dict]:
    if level == "smoke":
        return [{"axis": "resolution", "x": 64 * 36, "size": (64, 36)}]
    if level == "full":
        widths, counts, rings = (160, 226, 320, 452, 640, 905, 1280), (1, 2, 4, 9, 18, 36, 72, 144), \
            (1, 2, 4, 8, 16, 32, 64)
        size = (480, 270)
    else:
        widths, counts, rings, size = (96, 192, 384), (4, 16, 64), (2, 8, 32), (128, 72)
    out = [{"axis": "resolution", "x": w * round(w * 9 / 16), "size": (w, round(w * 9 / 16))} for w in widths]
    out += [{"axis": "containers", "x": n, "size": size} for n in counts]
    out += [{"axis": "rings", "x": k, "size": size} for k in rings]
    return out


def scaling_run(env: Env, cfg: dict) -> list[Row]:
    axis, x, size = cfg["axis"], cfg["x"], tuple(cfg["size"])
    if axis == "resolution":
        p = Params({"scene.count": 24 if env.level == "full" else 8, **UNFILTERED})
        scene = build_scene(p)
        cam = Camera.from_params(p, scene)
    elif axis == "containers":
        p, scene, cam = grid_scene(int(x))
    else:
        p, scene, cam = single_container(int(x), 100, fiber_radius=0.5 / 64)
    env.virtual.set_scene(scene)
    rows = []
    for mode in ("fast", "exact"):
        r = {"axis": axis, "x": x, "method": f"virtual-{mode}", "width": size[0], "height": size[1]}
        r.update(_timing_row("", env.time_virtual(p, cam, size, mode)))
        rows.append(r)
    if axis != "rings":
        env.explicit.set_scene(scene, p)
        r = {"axis": axis, "x": x, "method": "explicit", "width": size[0], "height": size[1]}
        r.update(_timing_row("", env.time_explicit(p, cam, size)))
        rows.append(r)
        env.drop_explicit()
    return rows


# --------------------------------------------------------------------------------------------------
SUITES: dict[str, Suite] = {s.name: s for s in (
    Suite("memory", "Memory and time against the number of fibers, virtual and explicit",
          "Table 2, Figures 37-38", memory_configs, memory_run, isolate=True,
          columns=[("fibers", "fibers"), ("method", "method"), ("status", "status"),
                   ("gpu_bytes", "GPU buffers"), ("needed_bytes", "would need"), ("rss_peak", "peak RSS"),
                   ("build_s", "build s"), ("ms", "ms/frame"), ("cv", "CV"), ("reps", "frames"),
                   ("fast_ms", "fast ms"),
                   ("coverage_agree", "coverage agree"), ("id_agree", "id agree"), ("color_diff", "colour diff")]),
    Suite("rings", "One container: rings x fibers per ring", "Table 3, Figure 41", rings_configs, rings_run,
          columns=[("rings", "rings"), ("per_ring", "fibers/ring"), ("method", "method"), ("ms", "ms/frame"),
                   ("cv", "CV"), ("tests_per_px", "tests/px"), ("covered", "covered")]),
    Suite("containers", "Overlapping containers, empty (2 fibers per ring) and full (360)", "Table 4",
          containers_configs, containers_run,
          columns=[("containers", "containers"), ("fill", "fill"), ("method", "method"), ("ms", "ms/frame"),
                   ("cv", "CV"), ("tests_per_px", "tests/px"), ("fragments_per_px", "fragments/px")]),
    Suite("accuracy", "Traversal modes: cost and agreement with brute force and the float64 reference",
          "Figures 16, 26-34 (modes and shapes)", accuracy_configs, accuracy_run,
          columns=[("shape", "shape"), ("mode", "mode"), ("ms", "ms/frame"), ("cv", "CV"),
                   ("tests_per_px", "tests/px"), ("tests_vs_brute", "brute/this tests"),
                   ("differ_brute_pct", "% px != brute"), ("differ_ref_pct_of_hit", "% hit px != float64")]),
    Suite("scaling", "Time against resolution, visible containers and rings, with fitted exponents", "-",
          scaling_configs, scaling_run,
          columns=[("axis", "axis"), ("x", "x"), ("method", "method"), ("ms", "ms/frame"), ("cv", "CV")]),
    Suite("grooms", "Real grooms per strand against the default preset, and Table 4's 200 vs 10 containers, "
          "in one process", "Table 4 (full, 10 and 200 containers)", grooms.configs, grooms.run,
          columns=grooms.COLUMNS),
    Suite("looks", "Each shared groom against its own strands: coverage IoU, orientation, contact sheets",
          "- (issue 15)", looks.configs, looks.run, columns=looks.COLUMNS),
)}


def thesis_table_2() -> list[tuple[int, float, float, float | None, float | None]]:
    """(fibers, proposed RAM MB, proposed s, Blender RAM MB, Blender s); None = crash."""
    return [(10_000, 147, 22.3, 321, 1.24), (20_000, 147, 23.7, 321, 1.3), (50_000, 147, 17.4, 575, 1.5),
            (100_000, 147, 16.48, 974, 1.93), (200_000, 147, 21.55, 1740, 2.73),
            (350_000, 147, 22.7, 2686, 3.9), (500_000, 147, 20.5, 3891, 7.7), (1_000_000, 147, 22.3, None, None)]

