"""A/B comparison: the current look (B, live) against a pinned one (A).

Pin a look (Compare > Pin current look, or the script step ``{ pin = "name" }``) and choose a mode:
``split`` shows A left of a movable line and B right of it, with the same camera; ``A only`` flips to
A (press it again and back: flipping is how artists spot small changes). A is rendered with the
pinned look and the *current* camera, so orbiting keeps both halves comparable; it is re-rendered only
once the live view has settled (the final frame), never while something moves.

The pinned look may come from another preset or groom: A has its own Renderer and scene.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..params import Params

if TYPE_CHECKING:
    from .host import ViewerHost

MODES = ("off", "split", "A only")


def compared_params(pinned: Params, live: Params) -> Params:
    """The pinned look seen through the live camera."""
    return pinned.replace(**{k: v for k, v in live.values.items() if k.startswith("camera.")})


class CompareView:
    def __init__(self, ctx):
        self.ctx = ctx
        self.renderer = None
        self.scene = None
        self._scene_key: tuple | None = None
        self._key: tuple | None = None
        self.texture = None
        self.image: np.ndarray | None = None     # A as last rendered (H, W, 3) uint8, top row first
        self.renders = 0

    def release(self) -> None:
        if self.texture is not None:
            self.texture.release()
            self.texture = None

    def _render_a(self, viewer: ViewerHost, size: tuple[int, int]) -> None:
        from ..render.renderer import Renderer
        from ..scene.generators import build_scene
        from .display import render_still
        from .navigate import make_camera

        s = viewer.state
        pa = compared_params(s.pinned, s.params)
        scene_key = tuple((k, v) for k, v in pa.values.items() if k.startswith("scene."))
        if self.renderer is None:
            self.renderer = Renderer(self.ctx, viewer.programs)
        self.renderer.programs = viewer.programs     # a shader hot reload swaps the viewer's cache
        if scene_key != self._scene_key:
            live_key = tuple((k, v) for k, v in s.params.values.items() if k.startswith("scene."))
            # the same hair as on screen: share the viewer's scene (its geometry), else build A's own
            self.scene = viewer.scene if live_key == scene_key and viewer.scene is not None else build_scene(pa)
            self.renderer.set_scene(self.scene)
            self._scene_key = scene_key
        cam = make_camera(pa, self.scene, size[0] / max(size[1], 1))
        self.image = render_still(self.renderer, pa, cam, size)
        self.renderer.release_targets()
        if self.texture is None or self.texture.size != size:
            self.release()
            self.texture = self.ctx.texture(size, 3, dtype="f1")
            self.texture.filter = (0x2601, 0x2601)        # GL_LINEAR
        self.texture.write(np.ascontiguousarray(self.image[::-1]).tobytes())
        self.renders += 1

    def draw(self, viewer: ViewerHost, rect: tuple[int, int, int, int]) -> None:
        """Bring A up to date (when B has settled) and draw it over B's render area."""
        s = viewer.state
        mode = s.view.compare
        if mode == "off" or s.pinned is None or viewer.scene is None:
            return
        x, y, w, h = rect
        key = (tuple(compared_params(s.pinned, s.params).values.items()), (w, h), id(viewer.programs))
        if key != self._key and (viewer.final_shown() or self.texture is None):
            self._key = key           # tried once per change, whether it works or not
            try:
                self._render_a(viewer, (w, h))
            except Exception as e:  # A's groom or HDRI may fail where B's did not: say so, show B alone
                s.status = f"error: the pinned look A does not render: {e}"
                self.release()
                return
        if self.texture is None:
            return
        split = w if mode == "A only" else int(round(w * min(max(s.view.compare_split, 0.0), 1.0)))
        if split <= 0:
            return
        prog = viewer.programs.get(self.ctx, "stages/fullscreen.vert", "viewer/compare.frag")
        ctx = self.ctx
        ctx.screen.use()
        ctx.disable(0x0B71 | 0x0BE2)      # DEPTH_TEST | BLEND: A replaces B's pixels
        ctx.viewport = rect
        ctx.scissor = (x, y, split, h)
        self.texture.use(0)
        prog["uImage"].value = 0
        if "uSplitX" in prog:
            prog["uSplitX"].value = float(x + split) if mode == "split" else -10.0
        vao = ctx.vertex_array(prog, [])
        vao.render(vertices=3)
        vao.release()
        ctx.scissor = None
