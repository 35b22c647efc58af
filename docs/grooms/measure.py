"""Make the numbers and thumbnails in docs/grooms.md: python docs/grooms/measure.py [name ...]

For each shared groom (one guide per strand, and one clustered variant) it measures, in one process so the
ratios compare: load time, scene build time, containers, fibers, GPU bytes (virtual, explicit baseline,
plain polylines), shader work per pixel (container fragments, loop iterations:
the same on any machine), milliseconds per 1280x720 exact-mode frame (median of 5 after one warm-up, ctx.finish()
and the colour read-back inside the clock), and agreement with the original strands at 320x180 (see
tests/render/test_groom_render.py). Writes docs/grooms/<stem>[-c<N>].png and docs/grooms/numbers.json.
"""

from __future__ import annotations

import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from app.gl.context import create_headless  # noqa: E402
from app.info import gpu_bytes  # noqa: E402
from app.params import Params  # noqa: E402
from app.render.camera import Camera  # noqa: E402
from app.render.renderer import Renderer  # noqa: E402
from app.scene.generators import build_scene  # noqa: E402
from app.scene.grooms import load_groom, scene_from_groom  # noqa: E402
from tests.render.test_groom_render import DATA, coverage, groom_params  # noqa: E402

OUT = Path(__file__).resolve().parent
SIZE = (1280, 720)
COVERAGE_SIZE = (320, 180)
RUNS = 5
CONFIGS = [("harolongo.data", 0), ("harolongo.data", 500), ("harolongo.data", 100),
           ("sintel_hair.tfx", 0), ("sintel_hair.tfx", 50), ("Ratboy_mohawk.tfx", 0), ("Ratboy_mohawk.tfx", 200),
           ("Bangs_100.hair", 0), ("Bangs_100.hair", 25), ("Curly_100.ply", 0), ("Curly_100.ply", 25)]


def frame_ms(gl, renderer, p, cam, size) -> tuple[float, list[float], np.ndarray]:
    frame = renderer.render(p, cam, size)                     # warm-up: program compile, targets
    gl.ctx.finish()
    times = []
    for _ in range(RUNS):
        t = time.perf_counter()
        frame = renderer.render(p, cam, size)
        gl.ctx.finish()
        times.append(1000 * (time.perf_counter() - t))
    return statistics.median(times), times, frame.color


def main(names: list[str]) -> None:
    gl = create_headless()
    renderer = Renderer(gl.ctx)
    rows = []
    base = Params({"quality.mode": "exact"})                 # the default carpet: 24 containers, for scale
    scene = build_scene(base)
    renderer.set_scene(scene)
    cam = Camera.from_params(base, scene)
    ms, times, _ = frame_ms(gl, renderer, base, cam, SIZE)
    cost = renderer.render(base, cam, COVERAGE_SIZE, outputs=("cost",)).cost
    rows.append({"config": "default parameters (carpet)", "containers": scene.n_segments, "ms": ms, "times": times,
                 "work": {"fragments_per_px": float(cost[..., 2].mean()),
                          "iterations_per_px": float(cost[..., 3].mean())}})
    print(rows[-1], flush=True)
    for name, cluster in CONFIGS:
        if names and name not in names:
            continue
        p = groom_params(name, scene__groom_cluster=cluster, quality__mode="exact")
        load = statistics.median(_timed(lambda: load_groom(DATA / name)) for _ in range(5))
        builds = [_timed(lambda: scene_from_groom(p)) for _ in range(3)]
        scene = scene_from_groom(p)
        src = scene.source
        renderer.set_scene(scene)
        cam = Camera.from_params(p, scene)
        ms, times, color = frame_ms(gl, renderer, p, cam, SIZE)
        stem = Path(name).stem + (f"-c{cluster}" if cluster else "")
        Image.fromarray(color).resize((480, 270), Image.LANCZOS).save(OUT / f"{stem}.png", optimize=True)
        small = renderer.render(p, cam, COVERAGE_SIZE, outputs=("ids", "cost"))
        cov = coverage(cam, scene, load_groom(DATA / name).strands, small.hit, COVERAGE_SIZE)
        # The work, independent of machine load: container fragments (proxy pixels whose shader ran) and
        # traversal loop iterations, per pixel of the image and per pixel that shows a fiber.
        work = {"fragments_per_px": float(small.cost[..., 2].mean()),
                "fragments_per_hit_px": float(small.cost[..., 2].sum() / max(small.hit.sum(), 1)),
                "iterations_per_px": float(small.cost[..., 3].mean())}
        sizes = gpu_bytes(scene, p)
        from app import reference
        fibers = reference.fiber_count(p, scene.n_guides)[1]
        # for the prose only, not a figure vfiber shows: the plainest explicit store, every fiber a float32
        # xyz polyline through its guide's joints (no width, tangent or colour)
        joints = scene.n_segments // max(scene.n_guides, 1) + 1
        sizes["polylines"] = (fibers * joints * 12, "float32 xyz polylines")
        rows.append({
            "config": stem, "file": name, "cluster": src.cluster, "strands": src.strands, "vertices": src.vertices,
            "guides": scene.n_guides, "segments": src.segments, "native": src.native, "containers": scene.n_segments,
            "radius_median": float(np.median(src.radii)), "fibers": fibers, "fibers_per_strand": fibers / src.strands,
            "load_s": load, "build_s": statistics.median(builds), "ms": ms, "times": times,
            "bytes": {k: v[0] for k, v in sizes.items()}, "coverage": cov, "work": work,
            "thumbnail": f"grooms/{stem}.png"})
        print(json.dumps(rows[-1]), flush=True)
    (OUT / "numbers.json").write_text(json.dumps({"size": SIZE, "renderer": gl.renderer, "rows": rows}, indent=1))


def _timed(fn) -> float:
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


if __name__ == "__main__":
    main(sys.argv[1:])
