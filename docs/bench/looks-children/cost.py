"""What Curly_100's interpolated children cost a frame: ``python docs/bench/looks-children/cost.py
docs/bench/looks-children``.

One process, 640x360, each groom's own camera; per mode (exact, fast) the variants are rendered in turn,
frame after frame (plain, auto without children, auto with its children), ``FRAMES`` rounds after one
warm-up round, each frame timed with ``time.process_time`` (it counts llvmpipe's threads) around the
render and its read-back. Writes cost.json: min and median ms per variant and mode, and the ratio of the
medians to the plain fill's.
"""
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[3]))
from app.bench.grooms import HAIR_DATA  # noqa: E402
from app.gl.context import create_headless  # noqa: E402
from app.presets import resolve_params  # noqa: E402
from app.render.camera import Camera  # noqa: E402
from app.render.renderer import Renderer  # noqa: E402
from app.scene.generators import build_scene  # noqa: E402

SIZE = (640, 360)
FRAMES = 8
VARIANTS = {"plain": ["fibers.groom_auto=false"], "auto, no children": ["scene.groom_children=0"],
            "defaults (auto, children)": []}


def main(out: Path, groom: str = "Curly_100.ply") -> None:
    ctx = create_headless().ctx
    path = str(HAIR_DATA / groom)
    made = {}
    for label, sets in VARIANTS.items():
        p, _ = resolve_params(path, sets)
        scene = build_scene(p)
        renderer = Renderer(ctx)                      # one each: no upload between the alternated frames
        renderer.set_scene(scene)
        made[label] = (p, scene, renderer)
    cam = Camera.from_params(made["plain"][0], made["plain"][1], aspect=SIZE[0] / SIZE[1])     # one camera
    result = {"groom": groom, "size": SIZE, "frames": FRAMES, "modes": {}}
    for mode in ("exact", "fast"):
        times: dict[str, list[float]] = {k: [] for k in made}
        for rnd in range(FRAMES + 1):
            for label, (p, _, renderer) in made.items():
                t0 = time.process_time()
                frame = renderer.render(p, cam, SIZE, outputs=("color", "ids"), mode=mode)
                dt = time.process_time() - t0
                if rnd:
                    times[label].append(1e3 * dt)
                assert frame.hit.any()
        base = float(np.median(times["plain"]))
        result["modes"][mode] = {k: {"min_ms": round(min(v), 1), "median_ms": round(float(np.median(v)), 1),
                                     "x_plain": round(float(np.median(v)) / base, 2),
                                     "containers": made[k][1].n_segments} for k, v in times.items()}
        print(mode, json.dumps(result["modes"][mode]), flush=True)
    out.mkdir(parents=True, exist_ok=True)
    (out / "cost.json").write_text(json.dumps(result, indent=1))


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "docs/bench/looks-children"))
