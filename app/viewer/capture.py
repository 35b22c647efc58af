"""Capture: pictures saved to files. ``screenshot`` renders offscreen without UI at any size, a grab saves
the window's pixels as displayed (the render area, or the whole window with ``ui``) when they are next shown
or once the final frame is complete, and File > Render turntable orbits the look offscreen one frame per
displayed frame. Scripts (app/viewer/script.py) drive all three."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .display import render_still
from .navigate import make_camera
from .script import emit


class Capture:
    """Screenshots, grabs and turntables (a part of ``Viewer``). A capture draws over or releases the
    window's targets, so it sets ``_shown_key`` to None and progressive refinement redraws the view."""

    def _init_capture(self) -> None:
        self._turntable: dict[str, Any] | None = None   # File > Render turntable in progress
        self._grab: tuple[str, bool, bool] | None = None

    def screenshot(self, path: str, size: tuple[int, int] | None = None, view: str = "shaded") -> None:
        """The render without UI at ``size`` (default: the viewport's), through the Renderer offscreen."""
        from PIL import Image

        s = self.state
        if self.scene is None:
            raise ValueError("no scene to render" + (f": {s.scene_error}" if s.scene_error else ""))
        if size is None:
            _, _, w, h = self._viewport_rect()
            size = (w, h)
        size = (int(size[0]), int(size[1]))
        cam = make_camera(s.params, self.scene, size[0] / max(size[1], 1))
        if self.vp.samples > 0 or self.vp.job is not None:
            self.vp.snapshot(self._viewport_rect()[2:])   # what the window shows stays, under the redraw
        if view == "shaded":
            img = render_still(self.renderer, s.params, cam, size)
        else:
            keep = self.vp.size
            self.vp.resize(size)
            if view == "heat map":
                self.vp.render_cost(s.params, cam, s.params["quality.mode"], size, upload=True)
                self.vp.samples = 1
            else:
                self.vp.render_sample(s.params, cam, s.params["quality.mode"], (0.0, 0.0), "readback", True)
            img = self.vp.display_offscreen(size, view, s.params, cam, self.scene, self._heat_max())
            self.vp.resize(keep)
            self._shown_key = None
        if size != self.vp.size:
            self.vp.park()
            self.renderer.release_targets()    # a 4K screenshot's targets are ~150 MB: do not keep them
        self.vp.invalidate()                   # the window's targets were drawn over or released
        self._cost_job = None
        self._shown_key = None                 # the view draws from the renderer's targets: redraw it
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        Image.fromarray(img).save(path)

    def render_turntable(self, path: str, frames: int = 36, size=(640, 360), alpha: bool = False) -> bool:
        """File > Render turntable: the current look orbited offscreen into ``path``, one frame per
        displayed frame (app/turntable.py), the status bar counting."""
        from ..turntable import iter_turntable

        s = self.state
        if self.scene is None:
            s.show_error("no scene to render" + (f": {s.scene_error}" if s.scene_error else ""))
            return False
        self._turntable = {"steps": iter_turntable(s.params, path, self.renderer, self.scene, frames=int(frames),
                                                    size=tuple(size), alpha=alpha),
                           "path": str(path), "frames": int(frames), "done": 0}
        return True

    def _turntable_step(self) -> None:
        job = self._turntable
        s = self.state
        try:
            job["done"], _ = next(job["steps"])
            s.status = f"turntable: frame {job['done']}/{job['frames']} in {job['path']}"
            return
        except StopIteration:
            from ..turntable import encode_video
            video, note = encode_video(Path(job["path"]), job["frames"])
            s.status = f"turntable: {job['done']} frames in {job['path']}" + (f", video {video}" if video else "")
            emit(turntable=job["path"], frames=job["done"], video=str(video or ""))
        except Exception as e:  # a full disk, a folder that cannot be made: say it, stay up
            s.show_error(f"{job['path']}: turntable failed: {e}")
        self._turntable = None
        self.vp.park()
        self.renderer.release_targets()
        self._shown_key = None

    def grab_pending(self) -> bool:
        return self._grab is not None

    def request_grab(self, path: str, final: bool = False, ui: bool = False) -> None:
        """Save the window's render area (``ui``: the whole window, panels included) when it is next shown
        (``final``: once the final frame is complete)."""
        self._grab = (path, final, ui)

    def _save_grab(self, rect) -> None:
        from PIL import Image

        path = self._grab[0]
        self._grab = None
        # blit the window's pixels into an offscreen target and read that: reading the default
        # framebuffer directly raises GL_INVALID_OPERATION in moderngl (it selects a colour attachment)
        w, h = rect[2], rect[3]
        tex = self.ctx.texture(self.framebuffer_size(), 4, dtype="f1")
        fbo = self.ctx.framebuffer([tex])
        try:
            self.ctx.copy_framebuffer(fbo, self.ctx.screen)  # the whole window, then crop to the render
            raw = fbo.read(viewport=rect, components=3, alignment=1)
        finally:
            self.ctx.screen.use()     # never leave moderngl pointing at a released framebuffer
            fbo.release()
            tex.release()
        img = np.frombuffer(raw, np.uint8).reshape(h, w, 3)[::-1]
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        Image.fromarray(img).save(path)
        emit(grab=path, size=[rect[2], rect[3]], label=self.state.stats.label)
