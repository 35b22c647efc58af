"""``python -m app.bench.lighting [--size WxH] [--reps N] [--preset NAME]``: what the extra lights cost.

Renders one preset with the key light only, with fill + rim, and with the environment (8 median-cut
lights), for both shading models, alternating the variants rep by rep in one process (timings on a
shared machine drift; alternating keeps the ratios fair). Prints median milliseconds and the ratio to
the key light alone.
"""

from __future__ import annotations

import argparse
import statistics
import time

VARIANTS = {
    "key only": {},
    "key + fill + rim": {"light.fill_intensity": 0.8, "light.rim_intensity": 2.0},
    "key + environment": {"light.environment": "studio"},
    "key + fill + rim + environment": {"light.fill_intensity": 0.8, "light.rim_intensity": 2.0,
                                       "light.environment": "studio"},
}


def main(argv: list[str] | None = None) -> int:
    from ..cli import parse_size, resolve_params
    from ..gl.context import create_headless
    from ..render.camera import Camera
    from ..render.renderer import Renderer
    from ..scene.generators import build_scene

    ap = argparse.ArgumentParser(prog="python -m app.bench.lighting", description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", default="640x360")
    ap.add_argument("--reps", type=int, default=7)
    ap.add_argument("--preset", default="default")
    args = ap.parse_args(argv)
    size = parse_size(args.size)
    base, label = resolve_params(args.preset, [])
    scene = build_scene(base)
    with create_headless() as gl:
        r = Renderer(gl.ctx)
        r.set_scene(scene)
        cam = Camera.from_params(base, scene, size[0] / size[1])
        print(f"{label}, {size[0]}x{size[1]}, {args.reps} reps alternated, median ms, on {gl.renderer}")
        for model in ("kajiya_kay", "marschner"):
            ps = {name: base.replace(**{"look.model": model, **v}) for name, v in VARIANTS.items()}
            times: dict[str, list[float]] = {name: [] for name in ps}
            for p in ps.values():                      # compile and warm every variant first
                r.render(p, cam, size, outputs=("color",))
            for _ in range(args.reps):
                for name, p in ps.items():
                    t0 = time.perf_counter()
                    r.render(p, cam, size, outputs=("color",))
                    times[name].append((time.perf_counter() - t0) * 1000)
            ref = statistics.median(times["key only"])
            for name, ts in times.items():
                m = statistics.median(ts)
                print(f"  {model:<10} {name:<32} {m:8.1f} ms  {m / ref:5.2f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
