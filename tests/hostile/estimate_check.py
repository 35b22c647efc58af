"""``python -m tests.hostile.estimate_check [W H]``: the work estimate (app/render/budget.py) against the
renderer's own count of fiber tests (the ``cost`` output, one ray per pixel) and the measured frame time,
for the looks the estimate's constants were fitted to. Prints one line per look; ratios > 1 overestimate."""

from __future__ import annotations

import sys
import time

from app.gl.context import create_headless
from app.params import Params
from app.render import budget
from app.render.camera import Camera
from app.render.renderer import Renderer
from app.scene.generators import build_scene

LOOKS = {
    "default": {},
    "brute": {"quality.mode": "brute"},
    "fast": {"quality.mode": "fast"},
    "64 rings": {"fibers.rings": 64, "fibers.fiber_radius": 0.007, "fibers.phi_step": 0.2},
    "curl": {"shape.curl_amplitude": 0.4, "shape.curl_frequency": 4},
    "twist": {"shape.twist": 2, "scene.segments": 4},
    "ellipsoid": {"shape.ellipsoid": 1},
    "supersample 3": {"quality.supersample": 3},
    "traced": {"look.self_shadow": "traced"},
    "2000 guides": {"scene.count": 2000},
    "bent segments": {"scene.count": 200, "scene.segments": 16, "scene.bend": 60},
}


def main(size: tuple[int, int]) -> None:
    with create_headless() as gl:
        renderer = Renderer(gl.ctx)
        print(f"{size[0]}x{size[1]} on {gl.renderer}")
        for name, values in LOOKS.items():
            p = Params(values)
            scene = build_scene(p)
            renderer.set_scene(scene)
            cam = Camera.from_params(p, scene, aspect=size[0] / size[1])
            est = budget.estimate(p, scene, size)
            tests = float(renderer.render(p, cam, size, outputs=("cost",)).cost[..., 0].sum())
            renderer.render(p, cam, size, outputs=("ids",))          # warm the program cache
            t0 = time.perf_counter()
            renderer.render(p, cam, size, outputs=("ids",))
            seconds = time.perf_counter() - t0
            one_ray = budget.estimate(p.replace(**{"quality.supersample": 1, "look.self_shadow": "off"}), scene,
                                      size).fiber_tests
            print(f"{name:14s} tests (1 ray) est/meas {one_ray / max(tests, 1):5.2f}   "
                  f"seconds est {est.seconds:8.3f} meas {seconds:8.3f}   draws {est.draws}")


if __name__ == "__main__":
    main((int(sys.argv[1]), int(sys.argv[2])) if len(sys.argv) > 2 else (320, 180))
