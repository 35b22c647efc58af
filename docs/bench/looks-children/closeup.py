"""Curly_100 close up, one camera for all: ``python docs/bench/looks-children/closeup.py
docs/bench/looks-children``. Writes closeup.png: the interpolated reference (the looks judge) | before (the
plain fill) | auto without children | the defaults (auto with 15 interpolated children), 640x360 each, the
camera at half the framing distance from the groom's centre (the plain scene's)."""
import sys
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
from app.scene.generators import build_scene  # noqa: E402

SIZE = (640, 360)


def main(out: Path) -> None:
    ctx = create_headless().ctx
    path = str(HAIR_DATA / "Curly_100.ply")
    p, _ = resolve_params(path, looks.REFERENCE_SETS)
    scene = build_scene(p)
    far = Camera.from_params(p, scene, aspect=SIZE[0] / SIZE[1])
    cam = Camera(far.target + (far.position - far.target) / 2.0, far.target, far.fov, far.near, far.far)
    ref = strand_reference.build(p, scene)
    tiles = [("reference (interpolated, the judge)",
              strand_reference.render(ctx, ref, p, cam, SIZE, ExplicitRenderer(ctx, budget_bytes=1 << 30)).color)]
    renderer = Renderer(ctx)
    for label, sets in (("before: plain fill", looks.REFERENCE_SETS),
                        ("auto, no children", ["scene.groom_children=0"]), ("after: the defaults (15 children)", [])):
        pv, _ = resolve_params(path, sets)
        renderer.set_scene(build_scene(pv))
        tiles.append((label, renderer.render_quality(pv, cam, SIZE, outputs=("color",)).color))
    assert all(np.asarray(t[1]).any() for t in tiles)
    compose_sheet(tiles, out / "closeup.png", cols=len(tiles))


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "docs/bench/looks-children"))
