"""Scene loading: a change of any ``scene.*`` value rebuilds the scene; a groom file is read and turned into
containers in a worker thread (numpy only; every GL call stays on the window's thread), so the window is up
and drawing while a big groom loads, first with its strands sketched as lines. The console gets a line per
stage (window up, first picture, first complete frame)."""

from __future__ import annotations

import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from ..render.bvh import build_bvh
from ..scene.containers import Scene
from ..scene.generators import build_scene
from .navigate import make_camera
from .startup import T_START

SLOW_SCENE_BUILD_S = 0.15               # slower than this: rebuild the scene when the slider is released


class SceneLoading:
    """The scene on screen and the one being built (a part of ``Viewer``). Adopting a scene uploads it
    (``vp.set_scene``) and sets ``_shown_key`` to None so that progressive refinement draws it."""

    def _init_loading(self) -> None:
        self.scene: Scene | None = None
        self._scene_key: tuple | None = None
        self._built_scene_key: tuple | None = None
        self._scene_build_s = 0.0
        self._loading: dict[str, Any] | None = None # a scene being built in a worker thread
        self._first_picture = False
        self._first_full = False

    def _update_scene(self) -> None:
        s = self.state
        key = tuple((k, v) for k, v in s.params.values.items() if k.startswith("scene."))
        if self._loading is not None and not self._loading_done(key):
            return
        if key == self._built_scene_key:
            s.scene_error = None
            return
        if key == self._scene_key and s.scene_error:
            return  # already failed with these values: wait for a change
        if s.dragging and self._scene_build_s > SLOW_SCENE_BUILD_S and self.scene is not None:
            s.status = "the scene rebuilds when you release the slider"
            return
        self._scene_key = key
        params = s.params
        if target_is_slow(params):                   # a groom can take seconds: build it beside the UI
            box: dict[str, Any] = {}
            name = Path(params["scene.groom_file"]).name
            try:
                size = f" ({Path(params['scene.groom_file']).stat().st_size / 1e6:.1f} MB)"
            except OSError:
                size = ""
            print(f"vfiber view: loading {name}{size}: reading strands, building containers...", file=sys.stderr,
                  flush=True)
            thread = threading.Thread(target=_build_into, args=(params, box), name="vfiber-scene", daemon=True)
            self._loading = {"key": key, "box": box, "thread": thread, "t0": time.perf_counter(), "name": name}
            s.status = f"loading {name}..."
            thread.start()
            return
        t0 = time.perf_counter()
        box = {}
        _build_into(params, box)
        self._adopt_scene(key, box, time.perf_counter() - t0)

    def loading(self) -> bool:
        """A scene is being built in the worker thread (scripts wait for it)."""
        return self._loading is not None

    def _loading_done(self, key: tuple) -> bool:
        """Take the worker's scene once it is built; False while it is still building."""
        job = self._loading
        if job["thread"].is_alive():
            self.state.status = f"loading {job['name']}... {time.perf_counter() - job['t0']:.0f} s"
            if "groom" in job["box"] and not job.get("sketched"):
                job["sketched"] = True
                self._sketch_strands(job["box"]["groom"])
            return False
        self._loading = None
        if self.state.status.startswith("loading "):
            self.state.status = ""
        wall = time.perf_counter() - job["t0"]
        if job["key"] == key:             # the parameters did not change meanwhile: use it
            self._adopt_scene(key, job["box"], wall, job["name"])
        return True

    def _sketch_strands(self, groom) -> None:
        """The first picture of a groom whose containers are still being built: its strands as lines."""
        t0 = time.perf_counter()
        preview = strand_scene(groom)
        if preview.n_segments == 0:
            return
        rect = self._viewport_rect()
        cam = make_camera(self.state.params, preview, rect[2] / max(rect[3], 1))
        self.vp.sketch(rect[2:], self.state.params, cam, preview)
        self.vp.drop_proxies()          # the sketch's buffer: the scene's own comes with it
        self.vp.invalidate()
        if not self._first_picture:
            self._first_picture = True
            print(f"vfiber view: first picture {time.perf_counter() - T_START:.2f} s after start: "
                  f"{groom.n_strands:,} strands sketched in {time.perf_counter() - t0:.2f} s while the containers "
                  f"are built", file=sys.stderr, flush=True)

    def _adopt_scene(self, key: tuple, box: dict[str, Any], wall: float, name: str | None = None) -> None:
        s = self.state
        if "error" in box:   # a groom that does not load, a generator that fails: keep the old scene
            s.scene_error = box["error"]
            if name:
                print(f"vfiber view: {name}: {box['error']}", file=sys.stderr, flush=True)
            return
        scene = box["scene"]
        self._scene_build_s = wall
        s.stats.scene_build_ms = wall * 1000
        if s.status.startswith("the scene rebuilds"):
            s.status = ""
        s.scene_error = None
        t0 = time.perf_counter()
        self.scene = scene
        self._built_scene_key = key
        self.vp.set_scene(scene, box.get("bvh"))
        self.ctx.finish()
        upload = time.perf_counter() - t0
        self._shown_key = None
        self._cost_key = None
        self._cost_job = None
        s.stats.guides = scene.n_guides
        s.stats.segments = scene.n_segments
        s.stats.scene_gpu_bytes = self.renderer.scene_gpu_bytes
        if name:
            src = getattr(scene, "source", None)
            seconds = {**(getattr(src, "seconds", None) or {}), "hierarchy": box.get("bvh_s", 0.0)}
            stages = ", ".join(f"{k} {v:.2f} s" for k, v in seconds.items())
            strands = f"{src.strands:,} strands -> " if src is not None else ""
            print(f"vfiber view: {name}: {strands}{scene.n_segments:,} container segments in {wall:.2f} s "
                  f"({stages}); {scene.nbytes / 1e6:.1f} MB uploaded in {upload:.2f} s", file=sys.stderr, flush=True)

    def _startup_lines(self, t: float) -> None:
        """Console lines for the first picture (any part of it) and the first complete frame."""
        if self._first_full or self.scene is None or not target_is_slow(self.state.params):
            return
        vp = self.vp
        some = vp.samples > 0 or (vp.job is not None and vp.job.fraction > 0)
        if some and not self._first_picture:
            self._first_picture = True
            part = "" if vp.samples > 0 else f" ({vp.job.fraction:.0%} of it; the rest refines)"
            print(f"vfiber view: first picture {t - T_START:.2f} s after start{part}", file=sys.stderr, flush=True)
        if vp.samples > 0 and self._shown_key is not None:
            self._first_full = True
            print(f"vfiber view: first complete frame {t - T_START:.2f} s after start ({self.state.stats.label}, "
                  f"fibers {self.state.stats.render_ms / 1000:.2f} s)", file=sys.stderr, flush=True)


def strand_scene(groom) -> Scene:
    """The strands of a groom as zero-radius segments between their own vertices: enough for the sketch
    (display.ViewportRenderer.sketch draws a container's axis when its radius is 0) and to frame the camera
    while the real containers are built."""
    points, offsets = groom.packed()
    inside = np.ones(max(len(points) - 1, 0), bool)
    inside[offsets[1:-1] - 1] = False                 # no segment from one strand's tip to the next's root
    a, b = points[:-1][inside], points[1:][inside]
    origin = 0.5 * (points.min(0) + points.max(0)) if len(points) else np.zeros(3)
    axis = b - a
    rows = np.zeros((len(a), 20))
    rows[:, 0:3], rows[:, 4:7] = a - origin, b - origin
    rows[:, 8:11], rows[:, 12:15] = axis, axis           # miter normals along the axis
    rows[:, 16] = 1.0                                     # a frame vector (unused at radius 0)
    rows[:, 19] = np.repeat(np.arange(len(offsets) - 1), np.diff(offsets) - 1)   # guide: the strand's colour
    return Scene(rows, origin, "strands", groom.n_strands)

def target_is_slow(params) -> bool:
    """Grooms can take seconds to read and render: they get a console line per stage."""
    return params["scene.generator"] == "groom"


def _build_into(params, box: dict[str, Any]) -> None:
    """Build the scene of ``params`` into ``box["scene"]``, or the reason it failed into ``box["error"]``
    (runs in the loading thread: numpy only, no GL). A groom's strands go into ``box["groom"]`` as soon as
    the file is read, before its containers are built, so the window can sketch them."""
    try:
        if params["scene.generator"] == "groom":      # grooms.scene_from_groom, in its two steps
            from ..scene.grooms import groom_scene, load_groom
            t0 = time.perf_counter()
            groom = load_groom(params["scene.groom_file"], up=params["scene.groom_up"],
                               scale=params["scene.groom_scale"])
            box["groom"] = groom
            scene = groom_scene(groom, params, {"load": time.perf_counter() - t0})
        else:
            scene = build_scene(params)
        if scene.n_segments == 0:
            raise ValueError("the parameters give no containers")
        # the walk's hierarchy too (numpy only): on the window's thread harolongo's froze the UI for ~2 s
        t0 = time.perf_counter()
        box["bvh"] = build_bvh(scene)
        box["bvh_s"] = time.perf_counter() - t0
        box["scene"] = scene
    except Exception as e:  # whatever a groom file or a generator raises: the viewer says it and stays up
        box["error"] = f"{type(e).__name__}: {e}"
