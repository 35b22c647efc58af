"""What ``vfiber info`` says about a scene: containers, fibers and the GPU bytes of both methods.

A face beside the command line and the viewer, not part of the scene: the byte figures are the renderers'
own (``Renderer`` for the virtual method, ``render.explicit.explicit_bytes`` for the explicit baseline), and
the scene layer sits before the renderer, so the report that needs both lives here.
"""

from __future__ import annotations

import numpy as np

from .fibers import fiber_count, ring_layout, tapered
from .params import Params
from .render import explicit
from .render.renderer import frame_gpu_bytes, scene_gpu_bytes
from .scene.containers import Scene
from .units import human_bytes

_W = 17  # label column width of the groom lines (app.scene.groom_info)


def info_lines(p: Params, scene: Scene, label: str) -> list[str]:
    """Every line ``vfiber info`` prints for ``scene`` built from ``p`` (``label``: where ``p`` came from)."""
    thesis, exact = fiber_count(p, scene.n_segments and scene.n_guides or 0)
    lay = ring_layout(p)
    lo, hi = scene.bounds()
    lines = [
        f"source           {label}",
        f"guides           {scene.n_guides}",
        f"container segs   {scene.n_segments}",
        # the containers' box (radii included); a groom also prints its strands' own box as "groom bbox"
        f"container box    {np.round(lo, 4).tolist()} .. {np.round(hi, 4).tolist()} (radii included)",
        f"rings            {lay.rings} (fibers per ring, outer to inner: "
        f"{', '.join(str(int(n)) for n in lay.n[:8])}{' ...' if lay.rings > 8 else ''})",
        f"fibers/container {lay.fibers_per_container}",
        f"fibers           {exact} exact; {thesis:.1f} by the thesis's expression 4.1",
        f"scene GPU bytes  {scene_gpu_bytes(scene)} (the same whatever the fiber count)",
        f"per-pixel bytes  {frame_gpu_bytes((1280, 720))} at 1280x720, {frame_gpu_bytes((640, 360))} at 640x360 "
        "(colour, ids, geometry, depth, walk state: sized by the image alone)",
    ]
    if hasattr(scene, "source_info"):
        from .scene.grooms.defaults import auto_report

        auto = auto_report(p)
        if auto:
            lines.append(f"groom auto       {auto}")
        lines += groom_lines(scene)
    return lines


def gpu_bytes(scene: Scene, p: Params) -> dict[str, tuple[int, str]]:
    """GPU bytes of the virtual scene and of the explicit baseline's store of the same fibers, each with its
    formula. ``virtual``: what ``Renderer.set_scene`` allocates (container segments plus the proxy
    rectangle). ``explicit``: what ``ExplicitRenderer.set_scene`` would allocate for exactly these fibers."""
    pl = explicit.plan(scene, p)
    return {
        "virtual": (scene_gpu_bytes(scene),
                    "container segments" + (" + per-guide colours" if scene.guide_colors is not None else "")
                    + " + their hierarchy + proxy rectangle (Renderer.set_scene)"),
        "explicit": (pl.gpu_bytes, f"ExplicitRenderer: {_instance_bytes(p)} B per fiber per segment "
                                   f"({pl.instances:,}) + {explicit.ROW_BYTES} B per segment"),
    }


def gpu_lines(scene: Scene, p: Params) -> list[str]:
    """The "GPU virtual" and "GPU explicit" lines of a groom's report."""
    sizes = gpu_bytes(scene, p)
    v, how = sizes["virtual"]
    b, how_explicit = sizes["explicit"]
    return [f"{'GPU virtual':<{_W}}{v:,} B ({human_bytes(v)}): {how}",
            f"{'GPU explicit':<{_W}}{b:,} B ({human_bytes(b)}), {b / max(v, 1):,.0f}x virtual: {how_explicit}"]


def groom_lines(scene, p: Params | None = None) -> list[str]:
    """A groom scene's own lines (file, strands, guides, fibers) with the GPU bytes among them; ``p``
    defaults to the parameters the scene was built with (a viewer that changed ``fibers.*`` since passes
    its current ones)."""
    p = p or scene.params or Params({})
    return scene.source_info(p, gpu_lines=gpu_lines(scene, p))


def _instance_bytes(p: Params) -> int:
    """Bytes per explicit fiber instance: tapered fibers also store where they end (render.explicit)."""
    return explicit.INSTANCE_BYTES + (explicit.TAPER_BYTES if tapered(p) else 0)

