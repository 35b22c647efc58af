"""The desktop lookdev viewer: a glfw window, imgui panels over the live GLSL render.

``run_viewer(target, script=..., size=...)`` is the entry point (``vfiber view`` calls it); ``python -m
app.viewer.app [TARGET] [--script FILE] [--size WxH]`` does the same from a shell.

One frame::

    events -> script step -> gui(state) (edits values) -> camera controller (edits camera.*)
           -> commands (screenshot, export, quit) -> scene rebuild if scene.* changed
           -> render(state): one fiber sample if the image is out of date -> display -> imgui -> swap

Speed for accuracy: while something changes (a slider held, the camera moving, the turntable) the fibers
render at the interactive scale (and fast mode by default); after ``refine_delay`` seconds of stillness
the final frame renders at ``quality.render_scale`` in ``quality.mode`` and then accumulates
``quality.supersample``^2 stratified samples. A sample that costs more than ``view.refine_budget_ms`` is drawn in
strips across UI frames (display.StripJob) over the picture that was on screen, with "refining n%" in the
corner, so input, menus and the panel keep running whatever a frame costs. When nothing is out of date the
loop sleeps in ``glfw.wait_events_timeout``.

Before a final frame starts, ``render.budget.estimate`` (the work ``vfiber render`` refuses past a minute
without ``--allow-slow``) is worked out for it: a look that takes more than ``NOTICE_SECONDS`` a frame says so
at the top of the panel and in the stats overlay while it is on screen, and a slow one (``WorkEstimate.slow``)
keeps the interactive preview until the person presses "Render anyway" (script step ``render_anyway``).

A groom file is read and turned into containers in a worker thread (numpy only; every GL call stays on
this thread), so the window is up and drawing while a big groom loads; the console gets a line per stage.
"""

from __future__ import annotations

import time

T_START = time.perf_counter()   # before the heavy imports: "first picture after n s" counts from here

# imgui_bundle first: it points pyGLFW at its own libglfw, so both talk to one glfw.
from imgui_bundle import imgui  # noqa: I001  (import order matters, see above)

import argparse
import ctypes
import importlib.util
import math
import statistics
import sys
import threading
from collections import deque
from pathlib import Path
from typing import Any

import numpy as np

from .. import reference
from ..gl.context import GLContextError, create_window
from ..gl.shaders import ProgramCache, ShaderError
from ..params import ParamError
from ..presets import PresetError, find_preset
from ..render import budget
from ..render.camera import Camera
from ..render.renderer import Renderer
from ..scene.containers import Scene
from ..scene.generators import build_scene
from .compare import CompareView
from .display import (CostModel, StripJob, ViewportRenderer, auto_scale, cost_stats, render_still, row_weights,
                      supersample_offsets)
from .gui import Layout, gui, refine_overlay
from .navigate import CameraController, Input, make_camera
from .script import Script, ScriptError, ScriptRunner, emit, load_script
from .state import AppState, explicit_bytes, is_groom_path, now

IDS_VIEWS = ("fiber ids", "rings", "normals", "depth")
COST_STATS_MAX_PIXELS = 640 * 360       # the occasional cost render for the stats overlay
SHADER_POLL_S = 0.5
SLOW_SCENE_BUILD_S = 0.15               # slower than this: rebuild the scene when the slider is released
FRAME_HISTORY = 30
INTERACTIVE_WHOLE = 1.5                 # interactive frames up to this times auto_budget_ms are drawn whole
NOTICE_SECONDS = 5.0                    # final frames estimated longer than this say so (as vfiber render does)


def _scale_fraction(name: str) -> float | None:
    return None if name == "auto" else float(name.rstrip("%")) / 100.0


class Viewer:
    def __init__(self, state: AppState, size: tuple[int, int] = (1280, 720), *, scripted: bool = False,
                 glsl_root: str | Path | None = None):
        import glfw

        self.glfw = glfw
        self.state = state
        self.scripted = scripted
        wc = create_window(int(size[0]), int(size[1]), state.title, visible=True)
        self.window, self.ctx = wc.window, wc.ctx
        glfw.swap_interval(0 if scripted else 1)
        self._init_imgui()
        self.programs = ProgramCache(glsl_root)
        self.renderer = Renderer(self.ctx, self.programs)
        self.vp = ViewportRenderer(self.ctx, self.renderer, self.programs)
        self.compare = CompareView(self.ctx)
        self._turntable: dict[str, Any] | None = None   # File > Render turntable in progress
        self.controller = CameraController()
        self.scene: Scene | None = None
        self._scene_key: tuple | None = None
        self._built_scene_key: tuple | None = None
        self._scene_build_s = 0.0
        self._shown_key: tuple | None = None       # what the accumulated image shows
        self._shown_quality = ""
        self._final_wanted = 1                      # samples the final frame accumulates
        self._cost_key: tuple | None = None
        self._estimate_key: tuple | None = None     # what state.stats.estimate was worked out for
        self._look_key: tuple | None = None         # the look "Render anyway" was pressed for
        self._watch: ProgramCache = self.programs   # the cache whose files are watched for hot reload
        self._fallback: ProgramCache | None = None  # the programs before the last reload
        self._last_shader_poll = 0.0
        self._latency_from: float | None = None
        self._frame_times: deque[float] = deque(maxlen=FRAME_HISTORY)
        self._ms_per_mpix: float | None = None
        self._drag_owned = [False, False, False]
        self._script_inputs: list[Input] = []
        self._grab: tuple[str, bool, bool] | None = None
        self._title = ""
        self._extra_frames = 2
        self._layout = Layout(0, 0, *size)
        self._last_frame = time.perf_counter()
        self._bench: dict[str, Any] | None = None
        self._job: dict[str, Any] | None = None     # the sample being refined: key, quality, scale, mode
        self._cost_job: tuple[tuple, StripJob] | None = None    # the overlay's cost render, in strips
        self._loading: dict[str, Any] | None = None # a scene being built in a worker thread
        self._weights = None                        # display.row_weights of the frame being drawn
        self._frame_fibers_s = 0.0
        self._ui_times: deque[float] = deque(maxlen=FRAME_HISTORY)   # frame time less its strips
        self._first_picture = False
        self._first_full = False
        self.gl_errors: list[str] = []
        self.exit_code: int | None = None
        self.state.stats.gl_renderer = f"{self.ctx.info['GL_RENDERER']} | {self.ctx.info['GL_VERSION']}"
        try:
            self.state.osl_available = importlib.util.find_spec("app.export.osl") is not None
        except ImportError:
            self.state.osl_available = False
        self._check_gl("startup")
        if target_is_slow(state.params):
            print(f"vfiber view: window up {time.perf_counter() - T_START:.2f} s after start", file=sys.stderr,
                  flush=True)

    # --- setup -------------------------------------------------------------------------------------
    def _init_imgui(self) -> None:
        glfw = self.glfw
        imgui.create_context()
        io = imgui.get_io()
        io.set_ini_filename("")                     # no imgui.ini beside the artist's files
        imgui.style_colors_dark()
        # HiDPI: the monitor's content scale, less what the framebuffer already scales (macOS windows are
        # sized in points with a 2x framebuffer; Windows and X11 windows are sized in pixels)
        content = max(glfw.get_window_content_scale(self.window))
        fb_w, _ = glfw.get_framebuffer_size(self.window)
        win_w, _ = glfw.get_window_size(self.window)
        scale = content / max(fb_w / max(win_w, 1), 1.0)
        style = imgui.get_style()
        style.window_rounding = 4.0
        if scale > 1.0:
            style.scale_all_sizes(scale)
            style.font_scale_dpi = scale
        # Our callbacks go in first: imgui's backend chains to them, and they tell the loop that an event
        # (not just a timeout) woke it, so an idle viewer draws nothing at all.
        def mark(*_args: Any) -> None:
            self._event = True
        for setter in (glfw.set_cursor_pos_callback, glfw.set_mouse_button_callback, glfw.set_scroll_callback,
                       glfw.set_key_callback, glfw.set_char_callback, glfw.set_window_size_callback,
                       glfw.set_framebuffer_size_callback, glfw.set_window_refresh_callback,
                       glfw.set_window_focus_callback, glfw.set_cursor_enter_callback,
                       glfw.set_window_content_scale_callback):
            setter(self.window, mark)
        self._event = True
        address = ctypes.cast(self.window, ctypes.c_void_p).value
        imgui.backends.glfw_init_for_opengl(address, True)
        imgui.backends.opengl3_init("#version 330")

    def close(self) -> None:
        imgui.backends.opengl3_shutdown()
        imgui.backends.glfw_shutdown()
        imgui.destroy_context()
        self.vp.release()
        self.compare.release()
        self.glfw.destroy_window(self.window)
        self.glfw.terminate()

    # --- the loop ----------------------------------------------------------------------------------
    def run(self, runner: ScriptRunner | None = None) -> int:
        glfw = self.glfw
        try:
            while self.exit_code is None:
                if not self._wait_for_events(runner) and not glfw.window_should_close(self.window):
                    self._poll_shaders()         # woken by the timeout alone: nothing to draw
                    continue
                if glfw.window_should_close(self.window):
                    glfw.set_window_should_close(self.window, False)
                    self.state.request("quit", force=runner is not None)
                self.frame(runner)
                if runner is not None and runner.exit_code is not None and self._grab is None:
                    self.exit_code = runner.exit_code
        finally:
            self.close()
        return self.exit_code or 0

    def _busy(self, runner: ScriptRunner | None) -> float:
        """Seconds the loop may sleep waiting for input (0: a frame is due now)."""
        s = self.state
        if self.glfw.get_window_attrib(self.window, self.glfw.ICONIFIED):
            return SHADER_POLL_S      # minimized: nothing to show, nothing to render
        if self._extra_frames > 0 or s.view.turntable or self._bench or self._grab or self._turntable:
            return 0.0
        if runner is not None and not runner.done:
            return 0.0
        if s.commands or self._script_inputs:
            return 0.0
        if self._loading is not None:
            return 0.2                # poll the worker (input still wakes the loop at once); frames
                                      # hold the GIL the numpy build in the worker needs
        want, _ = self._plan()
        if want in ("new", "sample", "refine"):
            return 0.0
        if want == "final-wait":  # interactive frame on screen: sleep until it is time to refine
            return max(s.view.refine_delay - (now() - s.last_change), 0.02)
        if self._shown_quality == "final" and self._shown_key != self._cost_key:
            return 0.0            # the overlay's cost render is due
        return SHADER_POLL_S

    def _wait_for_events(self, runner: ScriptRunner | None) -> bool:
        """Poll or sleep for input. False when a sleep ended without any event and nothing is due."""
        timeout = self._busy(runner)
        if timeout <= 0:
            self.glfw.poll_events()
            self._extra_frames = max(0, self._extra_frames - 1)
            return True
        self._event = False
        self.glfw.wait_events_timeout(timeout)
        if self._event:
            self._extra_frames = 2   # imgui settles hover and popups over a couple of frames
            return True
        return self._busy(runner) <= 0 or timeout < SHADER_POLL_S

    def frame(self, runner: ScriptRunner | None = None) -> None:
        t0 = time.perf_counter()
        refining = self.vp.job is not None or self._cost_job is not None
        self._frame_fibers_s = 0.0          # strips drawn in this frame (the rest is UI and display)
        dt, self._last_frame = t0 - self._last_frame, t0
        self._poll_shaders()
        if runner is not None:
            runner.tick(self)
        imgui.backends.opengl3_new_frame()
        imgui.backends.glfw_new_frame()
        imgui.new_frame()
        self._layout = gui(self.state)
        refine_overlay(self.state, self._layout)
        self._navigate(dt)
        self._commands()
        if self._turntable is not None:
            self._turntable_step()
        self._update_scene()
        rendered = self.render()
        running = self._job is not None and self.vp.job is not None
        self.state.stats.drawing = self._job["quality"] if running else ""
        rect = self._viewport_rect()
        self.ctx.screen.use()
        self.ctx.viewport = (0, 0) + self.framebuffer_size()
        self.ctx.clear(0.1, 0.1, 0.11, 1.0)
        self.vp.display(self.ctx.screen, rect, self.state.view.view, self.state.params, self._camera(rect),
                        self.scene, self._heat_max())
        if self.state.view.view == "shaded":
            self.compare.draw(self, rect)
        grab_now = self._grab is not None and (not self._grab[1] or self.final_shown())
        if grab_now and not self._grab[2]:
            self._save_grab(rect)
        imgui.render()
        self.ctx.screen.use()
        self.ctx.viewport = (0, 0) + self.framebuffer_size()
        imgui.backends.opengl3_render_draw_data(imgui.get_draw_data())
        if grab_now and self._grab is not None:  # with the UI: the whole window
            self._save_grab((0, 0) + self.framebuffer_size())
        self.glfw.swap_buffers(self.window)
        done = time.perf_counter()
        self._startup_lines(done)
        if rendered:
            self._frame_times.append(done - t0)
            self.state.stats.frame_ms = statistics.median(self._frame_times) * 1000
            if self._latency_from is not None:
                self.state.stats.edit_latency_ms = (done - self._latency_from) * 1000
                self._latency_from = None
        if self._frame_fibers_s > 0:
            self._ui_times.append(done - t0 - self._frame_fibers_s)
        if self._bench is not None and (self._bench["quality"] != "refining" or refining):
            self._bench["frames"].append(done - t0)
            self._bench["fibers"].append(self._frame_fibers_s)
        self._check_gl("frame")
        if self.state.title != self._title:
            self._title = self.state.title
            self.glfw.set_window_title(self.window, self._title)

    # --- geometry ----------------------------------------------------------------------------------
    def framebuffer_size(self) -> tuple[int, int]:
        w, h = self.glfw.get_framebuffer_size(self.window)
        return max(int(w), 1), max(int(h), 1)

    def _viewport_rect(self) -> tuple[int, int, int, int]:
        """The render area in framebuffer pixels, GL origin (HiDPI: points times the framebuffer scale)."""
        fw, fh = self.framebuffer_size()
        io = imgui.get_io()
        sx = fw / max(io.display_size.x, 1.0)
        sy = fh / max(io.display_size.y, 1.0)
        L = self._layout
        x, w = int(round(L.x * sx)), int(round(L.w * sx))
        h = int(round(L.h * sy))
        y = fh - int(round(L.y * sy)) - h
        return max(x, 0), max(y, 0), max(min(w, fw), 1), max(min(h, fh), 1)

    def _camera(self, rect) -> Camera | None:
        if self.scene is None:
            return None
        return make_camera(self.state.params, self.scene, rect[2] / max(rect[3], 1))

    # --- input -------------------------------------------------------------------------------------
    def script_input(self, inp: Input) -> None:
        self._script_inputs.append(inp)

    def _navigate(self, dt: float) -> None:
        s = self.state
        inputs = self._script_inputs
        self._script_inputs = []
        inputs.append(self._input_from_imgui(dt))
        for inp in inputs:
            for key in list(inp.keys):
                if key.isdigit() and 1 <= int(key) <= 7:
                    from .state import VIEWS
                    s.view.view = VIEWS[int(key) - 1]
                    s.touch()
            if self.controller.update(s, self.scene, inp, self._viewport_rect()[2:]) and self.controller.moving:
                s.dragging = True

    def _input_from_imgui(self, dt: float) -> Input:
        io = imgui.get_io()
        fw, _ = self.framebuffer_size()
        scale = fw / max(io.display_size.x, 1.0)
        L = self._layout
        mx, my = io.mouse_pos.x, io.mouse_pos.y
        inside = L.x <= mx < L.x + L.w and L.y <= my < L.y + L.h
        for b in range(3):
            if imgui.is_mouse_clicked(b) and inside and not io.want_capture_mouse:
                self._drag_owned[b] = True
            if not imgui.is_mouse_down(b):
                self._drag_owned[b] = False
        inp = Input(dt=dt, shift=io.key_shift, ctrl=io.key_ctrl, alt=io.key_alt,
                    left=self._drag_owned[0], right=self._drag_owned[1], middle=self._drag_owned[2])
        if any(self._drag_owned):
            inp.dx, inp.dy = io.mouse_delta.x * scale, io.mouse_delta.y * scale
            if not math.isfinite(inp.dx) or not math.isfinite(inp.dy):
                inp.dx = inp.dy = 0.0
        if inside and not io.want_capture_mouse:
            inp.wheel = io.mouse_wheel
        typing = io.want_text_input or imgui.is_popup_open("", imgui.PopupFlags_.any_popup_id)
        if not typing and not io.key_ctrl:
            K = imgui.Key
            once = {"F": K.f, "HOME": K.home, "R": K.r, "T": K.t}
            repeat = {"LEFT": K.left_arrow, "RIGHT": K.right_arrow, "UP": K.up_arrow, "DOWN": K.down_arrow,
                      "PLUS": K.keypad_add, "MINUS": K.keypad_subtract, "PAGE_UP": K.page_up,
                      "PAGE_DOWN": K.page_down}
            for name, key in once.items():
                if imgui.is_key_pressed(key, False):
                    inp.keys.add(name)
            for name, key in repeat.items():
                if imgui.is_key_pressed(key, True):
                    inp.keys.add(name)
            if imgui.is_key_pressed(K.equal, True):
                inp.keys.add("PLUS")
            if imgui.is_key_pressed(K.minus, True):
                inp.keys.add("MINUS")
        return inp

    # --- commands from the gui or a script ----------------------------------------------------------
    def _commands(self) -> None:
        s = self.state
        while s.commands:
            command, args = s.commands.pop(0)
            if command == "quit":
                s.guard("Quit", self._stop, discard=bool(args.get("force")) or self.scripted)
            elif command == "screenshot":
                try:
                    self.screenshot(args["path"], args.get("size"), args.get("view", "shaded"))
                    s.status = f"saved {args['path']}"
                except Exception as e:  # a full disk, an MSAA count this GL lacks...: say it, stay up
                    s.show_error(f"{args['path']}: could not save the screenshot: {e}")
            elif command == "export_osl":
                self.export_osl(args["path"])
            elif command == "turntable":
                self.render_turntable(**args)
            elif command == "export_blend":
                self.export_blend(args["path"])
            elif command == "ask_save_as":
                s.commands.insert(0, (command, args))  # the gui opens the dialog next frame
                break

    def _stop(self) -> None:
        self.exit_code = 0

    def export_osl(self, path: str) -> bool:
        """File > Export OSL: the current parameters as an OSL shader (app.export.osl, imported lazily)."""
        s = self.state
        try:
            from ..export import osl  # lazy: the exporter is optional
        except ImportError as e:
            s.show_error(f"OSL export is not available: {e}")
            return False
        try:
            osl.export_osl(s.params, path)
        except Exception as e:  # whatever the exporter raises, the viewer stays up and says it
            s.show_error(f"{path}: OSL export failed: {e}")
            return False
        s.status = f"exported {path}"
        return True

    def export_blend(self, path: str) -> bool:
        """File > Export Blender scene: the current parameters as a .blend (app.export.blend, in a child
        process so bpy never shares this GL process), at the size of the view."""
        s = self.state
        try:
            from ..export import blend
            size = (max(16, int(self._layout.w)), max(16, int(self._layout.h)))
            s.status = blend.export_blend_in_child(s.params, path, size)
        except Exception as e:  # whatever the exporter says, the viewer stays up and shows it
            s.show_error(f"{path}: Blender export failed: {e}")
            return False
        return True

    # --- scene -------------------------------------------------------------------------------------
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
        self.vp.set_scene(scene)
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
            stages = ", ".join(f"{k} {v:.2f} s" for k, v in (getattr(src, "seconds", None) or {}).items())
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

    def _update_counts(self) -> None:
        s, scene = self.state, self.scene
        if scene is None:
            return
        f41, exact = reference.fiber_count(s.params, scene.n_guides)
        per_container = reference.ring_layout(s.params).fibers_per_container
        s.stats.fibers_41, s.stats.fibers_exact = f41, exact
        s.stats.explicit_bytes = explicit_bytes(per_container, scene.n_segments)

    # --- render(state): never touches imgui --------------------------------------------------------
    def _update_estimate(self) -> None:
        """The final frame's budget.estimate in plain words (cached by parameters, scene and view size)."""
        s = self.state
        size = self._viewport_rect()[2:]
        values = tuple(s.params.values.items())
        key = (values, id(self.scene), size)
        if key == self._estimate_key:
            return
        self._estimate_key = key
        look = (tuple(kv for kv in values if not kv[0].startswith("camera.")), id(self.scene))
        if look != self._look_key:          # "Render anyway" holds for the look it was pressed for
            self._look_key = look
            s.slow_confirmed = False
        try:
            est = budget.estimate(s.params, self.scene, size)
        except Exception:  # noqa: BLE001 - an estimate never stops the viewer
            est = None
        s.stats.estimate_slow = bool(est and est.slow)
        s.stats.estimate_seconds = est.seconds if est else 0.0
        s.stats.estimate = estimate_text(est, s.stats.gl_renderer) if est and est.seconds > NOTICE_SECONDS else ""

    def _quality(self) -> tuple[str, float, str]:
        """(\"final\" | \"interactive\", scale, mode) for the next sample."""
        s = self.state
        p = s.params
        moving = s.dragging or s.view.turntable or (now() - s.last_change) < s.view.refine_delay
        if not (s.dragging or s.view.turntable):
            # once a gesture ends, not every frame of it: 32,000 segments take ~40 ms to estimate here
            self._update_estimate()
        if self._bench_forces():
            moving = self._bench["quality"] == "interactive"
        elif s.final_held:                  # a slow look: the preview stays until "Render anyway"
            moving = True
        if not moving:
            return "final", p["quality.render_scale"], p["quality.mode"]
        frac = _scale_fraction(s.view.interactive_scale)
        if frac is None:
            rect = self._viewport_rect()
            frac = auto_scale(self._ms_per_mpix, rect[2] * rect[3] * p["quality.render_scale"] ** 2 / 1e6,
                              s.view.auto_budget_ms)
        mode = "fast" if s.view.interactive_mode == "fast" else p["quality.mode"]
        return "interactive", p["quality.render_scale"] * frac, mode

    def _render_size(self, scale: float) -> tuple[int, int]:
        _, _, w, h = self._viewport_rect()
        return max(1, round(w * scale)), max(1, round(h * scale))

    def _plan(self) -> tuple[str | None, tuple]:
        """What the next render should be: (None | \"new\" | \"sample\" | \"refine\" | \"final-wait\" |
        \"held\" (a slow look's preview, waiting for "Render anyway"), key)."""
        s = self.state
        if self.scene is None:
            return None, ()
        quality, scale, mode = self._quality()
        size = self._render_size(scale)
        key = (tuple(s.params.values.items()), s.view.view, size, mode, s.view.frame_path, quality,
               id(self.scene), id(self.programs))
        job = self._job
        if job is not None and self.vp.job is not None:
            if key == job["key"]:
                return "refine", key
            # while things keep moving, an interactive frame is finished before the newest one starts:
            # a picture every few UI frames beats strips of a picture that is never completed
            same_view = key[1:5] == job["key"][1:5] and key[6:] == job["key"][6:]
            if job["quality"] == quality == "interactive" and same_view:
                return "refine", job["key"]
        if key != self._shown_key or self._bench_forces():
            return "new", key
        if quality == "final" and s.view.view in ("shaded", "proxies") and self.vp.samples < self._final_wanted:
            return "sample", key
        if quality == "interactive":
            return ("held" if self.state.final_held else "final-wait"), key
        return None, key

    def final_shown(self) -> bool:
        what, _ = self._plan()
        return what is None and self._shown_quality == "final"

    def render(self) -> bool:
        """Bring the fiber image up to date: start a sample, or draw more of the running one (about
        view.refine_budget_ms of fibers per UI frame). Returns True when it drew fibers."""
        s = self.state
        what, key = self._plan()
        if what == "refine":
            return self._refine()
        if what not in ("new", "sample"):
            self._maybe_cost_stats()
            return False
        quality, scale, mode = self._quality()
        size = key[2]
        cam = make_camera(s.params, self.scene, size[0] / max(size[1], 1))
        # MSAA happens inside one renderer pass (with the shader's supersampling if both are set); plain
        # supersampling accumulates one stratified sample per frame
        one_pass_aa = quality == "final" and s.params["quality.msaa"] > 0
        if what == "new":
            self._update_counts()
            self._cost_job = None
            weights = self._weights = row_weights(self.scene, cam, size)
            model = self.vp.models.get(("draw", mode, one_pass_aa))
            predicted = model.predict(weights.sum()) if model else None
            refines = predicted is None or predicted > self._budget(quality)
            if refines:                       # it will take several UI frames: keep the old picture
                if self.vp.samples == 0 and self.vp.job is None:   # none of this scene yet: a sketch
                    self.vp.sketch(self._viewport_rect()[2:], s.params, cam, self.scene)
                else:
                    self.vp.snapshot(self._viewport_rect()[2:])
            self.vp.resize(size)
            self.vp.invalidate()
            accumulates = quality == "final" and s.view.view in ("shaded", "proxies") and not one_pass_aa
            self._final_wanted = s.params["quality.supersample"] ** 2 if accumulates else 1
            if s.last_edit is not None:
                self._latency_from, s.last_edit = s.last_edit, None
        offsets = supersample_offsets(s.params["quality.supersample"]) if quality == "final" else [(0.0, 0.0)]
        offset = offsets[self.vp.samples % len(offsets)]
        self._job = {"key": key, "quality": quality, "scale": scale, "mode": mode, "cam": cam}
        try:
            if s.view.view == "heat map":
                self._final_wanted = 1
                self.vp.begin_cost(s.params, cam, mode, weights=self._weights)
                return self._refine()
            elif s.view.frame_path == "direct" and not one_pass_aa:
                self.vp.begin_sample(s.params, cam, mode, offset, weights=self._weights)
                return self._refine()
            else:
                timing = self.vp.render_sample(s.params, cam, mode, offset, s.view.frame_path,
                                               with_ids=s.view.view in IDS_VIEWS, antialias=one_pass_aa)
                self._sample_done(timing.best_s, timing.clock)
        except ShaderError as e:
            self._shader_failed(e)
            return False
        except ParamError as e:  # a value this OpenGL cannot do (e.g. more MSAA samples than it has)
            s.errors[e.key or "quality.mode"] = e.bare
            s.status = f"error: {e}"
            self._shown_key = key     # do not retry every frame; a change of any value tries again
            self._job = None
            return False
        return True

    def _refine(self) -> bool:
        """Draw more of the running sample; book it once complete."""
        job = self.vp.job
        t0 = time.perf_counter()
        try:
            done = job is None or self.vp.refine(self._budget(self._job["quality"] if self._job else "final"))
        except ShaderError as e:      # a variant first compiled by this strip
            self.vp.invalidate()
            self._job = None
            self._shader_failed(e)
            return False
        self._frame_fibers_s += time.perf_counter() - t0
        if not done:
            self._show_progress()
            return True
        if self.state.view.view == "heat map" and self.vp.cost_stats is not None:
            self._publish_cost(self.vp.cost_stats)
        self._sample_done(job.spent_s, "wall")
        return True

    def _budget(self, quality: str) -> float:
        """Fiber seconds per UI frame for a sample of this quality."""
        if self._bench_forces():          # a bench of final or interactive frames times whole frames
            return math.inf
        budget = self.state.view.refine_budget_ms / 1000
        if quality == "interactive":
            # an interactive frame near its aim is drawn whole, as a moving picture must be; only one far
            # past it (a frame of seconds) is drawn in strips
            return max(budget, INTERACTIVE_WHOLE * self.state.view.auto_budget_ms / 1000)
        # at least as long as the UI's own part of a frame: where the UI is slow (a loaded machine) strips
        # of 30 ms would leave the refinement a fraction of the time and the frame take many times longer
        ui = statistics.median(self._ui_times) if self._ui_times else 0.0
        return max(budget, ui)

    def _show_progress(self) -> None:
        job = self.vp.job
        st = self.state.stats
        if job is None:
            st.refining = None
            return
        wanted = max(self._final_wanted, 1)
        st.refining = (self.vp.samples + job.fraction) / wanted

    def _sample_done(self, seconds: float, clock: str) -> None:
        s, job = self.state, self._job
        self._job = None
        s.stats.refining = None
        if job is None:
            return
        key, quality, scale, mode = job["key"], job["quality"], job["scale"], job["mode"]
        size = key[2]
        s.stats.render_ms, s.stats.render_clock = seconds * 1000, clock
        mpix = size[0] * size[1] / 1e6
        if mpix > 0 and s.view.view != "heat map":
            rate = seconds * 1000 / mpix
            self._ms_per_mpix = rate if self._ms_per_mpix is None else 0.5 * (self._ms_per_mpix + rate)
        if self._bench is not None:
            self._bench["render"].append(s.stats.render_ms)
            self._bench["size"] = size
        self._shown_key = key
        self._shown_quality = quality
        pct = f"{scale * 100:.0f}%"
        if quality == "final":
            extra = f" {pct}" if scale != 1.0 else ""
            s.stats.label = f"final {mode}{extra}"
        else:
            s.stats.label = f"interactive {pct} {mode}"
        s.stats.render_size = size
        s.stats.samples = (self.vp.samples, self._final_wanted)
        s.stats.depth_range = self.vp.depth_range(job["cam"], self.scene)
        # per-pixel buffers beside the scene's bytes: the renderer's at this size (its own count; None from
        # a renderer that keeps none) and the viewer's (accumulation, uploads, base pictures)
        hook = getattr(self.renderer, "frame_gpu_bytes", None)
        s.stats.frame_gpu_bytes = int(hook(size)) if hook is not None else None
        s.stats.viewer_gpu_bytes = self.vp.buffer_bytes()

    def _heat_max(self) -> float:
        s = self.state
        return s.view.heat_max or max(s.stats.tests_p99, 1.0)

    def _publish_cost(self, stats) -> None:
        st = self.state.stats
        st.tests_per_pixel, st.tests_p99 = stats.mean_tests, stats.p99_tests
        st.covered_pixels, st.cost_size = stats.covered, stats.size
        st.cost_age_s = 0.0

    def _maybe_cost_stats(self) -> None:
        """The overlay's fiber tests per pixel: a small cost render once the view has settled, drawn in
        strips like a slow frame."""
        s = self.state
        if self.vp.cost_stats is not None:
            s.stats.cost_age_s = time.perf_counter() - self.vp.cost_stats.at
        if self.scene is None or self._shown_quality != "final" or self._shown_key == self._cost_key:
            return
        if s.view.view == "heat map":
            self._cost_key = self._shown_key
            return
        if self._cost_job is None or self._cost_job[0] != self._shown_key:
            w, h = self._render_size(1.0)
            k = min(1.0, math.sqrt(COST_STATS_MAX_PIXELS / (w * h)))
            size = (max(1, int(w * k)), max(1, int(h * k)))
            p, mode = s.params, s.params["quality.mode"]
            cam = make_camera(p, self.scene, w / max(h, 1))

            def draw(region):
                return self.renderer.render(p, cam, size, outputs=("cost",), mode=mode, region=region)
            model = self.vp.models.setdefault(("cost", mode), CostModel())
            job = StripJob(size, draw, model, self.ctx.finish, row_weights(self.scene, cam, size))
            self._cost_job = (self._shown_key, job)
        job = self._cost_job[1]
        try:
            done = job.step(self._budget("final"))
        except ShaderError as e:
            self._cost_job = None
            self._shader_failed(e)
            return
        if not done:
            return
        self.vp.cost_stats = stats = cost_stats(job.last.cost, job.size)
        self._publish_cost(stats)
        self._cost_key = self._shown_key
        self._cost_job = None

    # --- shaders -----------------------------------------------------------------------------------
    def _poll_shaders(self) -> None:
        t = time.perf_counter()
        if t - self._last_shader_poll < SHADER_POLL_S:
            return
        self._last_shader_poll = t
        if not self._watch.sources_changed():
            return
        self.reload_shaders()

    def reload_shaders(self) -> bool:
        """Compile everything on screen with a fresh cache; swap only when all of it compiles."""
        s = self.state
        fresh = ProgramCache(self.programs.root)
        self._watch = fresh
        old = self.renderer.programs
        self.renderer.programs = fresh
        try:
            modes = {s.params["quality.mode"], "fast"}
            for mode in modes:
                self.renderer.compile_programs(s.params, mode)
            self.renderer.compile_programs(s.params, s.params["quality.mode"], cost=True)
            self.vp.compile_all(fresh)
        except ShaderError as e:
            self.renderer.programs = old
            s.shader_error = str(e)   # shown in the panel, not as a dialog: saving a file is not an event
            s.status = "error: shader reload failed (see the panel); the last good program stays on screen"
            return False
        self._fallback = self.programs
        self.programs = fresh
        self.vp.programs = fresh
        s.shader_error = None
        s.status = "shaders reloaded"
        self._shown_key = None
        return True

    def _shader_failed(self, e: ShaderError) -> None:
        """A variant that was not compiled ahead failed: go back to the previous programs if we have them."""
        s = self.state
        s.shader_error = str(e)
        s.status = "error: shader compile failed (see the panel)"
        if self._fallback is not None:
            self.programs = self.renderer.programs = self.vp.programs = self._fallback
            self._fallback = None
            self._shown_key = None

    # --- screenshots, grabs ------------------------------------------------------------------------
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

    def resize_window(self, width: int, height: int) -> None:
        """Resize as a person dragging the window edge would (scripts and tests)."""
        self.glfw.set_window_size(self.window, int(width), int(height))
        self._event = True

    def mouse_event(self, event: list, button: int = 0) -> None:
        """One mouse event in window coordinates: the pointer really moves (the glfw backend reads it back
        every frame); the button goes into imgui's queue as the backend's callback would put it."""
        io = imgui.get_io()
        self.glfw.set_cursor_pos(self.window, float(event[0]), float(event[1]))
        io.add_mouse_pos_event(float(event[0]), float(event[1]))
        if len(event) > 2:
            io.add_mouse_button_event(button, event[2] == "down")
        self._event = True

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

    # --- benchmarks (script "bench") ---------------------------------------------------------------
    def _bench_forces(self) -> bool:
        """A bench of "final" or "interactive" frames renders a whole new frame every UI frame."""
        return self._bench is not None and self._bench["quality"] in ("final", "interactive")

    def bench_begin(self, quality: str) -> None:
        self._bench = {"quality": quality, "frames": [], "render": [], "fibers": [], "size": None}

    def bench_frames(self) -> int:
        return len(self._bench["frames"]) if self._bench else 0

    def bench_end(self) -> dict[str, Any]:
        b, self._bench = self._bench or {}, None
        frames, render = b.get("frames", []), b.get("render", [])
        self._shown_key = None
        return {"quality": b.get("quality"), "path": self.state.view.frame_path, "size": b.get("size"),
                "frames": len(frames), "frame_ms_median": statistics.median(frames) * 1000 if frames else None,
                "render_ms_median": statistics.median(render) if render else None,
                # fiber strips inside those frames (refining): the frame less this is UI, display and swap
                "fibers_ms_median": statistics.median(b["fibers"]) * 1000 if b.get("fibers") else None,
                "frame_ms": [round(f * 1000, 1) for f in frames]}

    # --- errors ------------------------------------------------------------------------------------
    def _check_gl(self, where: str) -> None:
        err = self.ctx.error
        if err != "GL_NO_ERROR":
            self.gl_errors.append(f"{where}: {err}")
            self.state.stats.gl_error = err
            print(f"vfiber view: OpenGL error after {where}: {err}", file=sys.stderr, flush=True)


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


def estimate_text(est: budget.WorkEstimate, gl_renderer: str) -> str:
    """What a long frame costs, in the words the panel shows: the throughput behind the seconds was measured
    on llvmpipe, so only there is it "this machine"."""
    where = "on this machine" if "llvmpipe" in gl_renderer.lower() else "on llvmpipe (a GPU is far faster)"
    text = f"this look takes about {budget._duration(est.seconds)} a frame {where}"
    if est.slow:
        text += "; the final frame waits for Render anyway, the preview still draws"
    return f"{text}: {est.summary()}"


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
        box["scene"] = scene
    except Exception as e:  # whatever a groom file or a generator raises: the viewer says it and stays up
        box["error"] = f"{type(e).__name__}: {e}"


# --- entry point -------------------------------------------------------------------------------------

def initial_state(target: str | None) -> AppState:
    """The document the viewer opens with. Raises PresetError/ParamError for a target it cannot use."""
    state = AppState()
    if target is None:
        state.saved = state.params
        return state
    if is_groom_path(target) and importlib.util.find_spec("app.scene.grooms") is not None:
        if not Path(target).is_file():
            raise PresetError(f"no groom file {target!r}", source=target)
        state.open_groom(target)
        state.preset_name = Path(target).name
        state.saved = state.params
        state.clear_history()
        return state
    state.adopt(find_preset(target))
    return state


def run_viewer(target: str | None, *, script: str | None = None, size=(1280, 720),
               glsl_root: str | None = None, overrides: dict[str, Any] | None = None) -> int:
    """Open the viewer on a preset (name or path) or a groom file; returns the process exit code.

    ``script``: a TOML/JSON script (see app/viewer/script.py) run one step per frame; the window stays
    open after it unless it ends with ``quit``. Exit codes: 0 fine, 1 no OpenGL window, 2 a bad target
    or script. ``glsl_root``: shaders from another folder (a copy to experiment in; hot reload follows it).
    ``overrides``: ``--set`` values on top of the target (unsaved changes of the opened document).
    """
    runner = None
    if script is not None:
        try:
            parsed: Script = load_script(script)
        except ScriptError as e:
            print(f"vfiber view: {e}", file=sys.stderr)
            return 2
        runner = ScriptRunner(parsed)
        if parsed.size:
            size = parsed.size
    try:
        state = initial_state(target)
        if overrides:
            state.edit_many(overrides, undoable=False)
    except ParamError as e:  # PresetError is a ParamError: the message names file, line, key, value
        print(f"vfiber view: {e}", file=sys.stderr)
        return 2
    try:
        viewer = Viewer(state, size, scripted=runner is not None, glsl_root=glsl_root)
    except GLContextError as e:
        print(f"vfiber view: {e}", file=sys.stderr)
        return 1
    return viewer.run(runner)


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(x) for x in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected WIDTHxHEIGHT, e.g. 1280x720") from None
    if w < 1 or h < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: width and height must be positive")
    return w, h


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="vfiber view", description="Interactive lookdev viewer.")
    ap.add_argument("target", nargs="?", help="preset name or path, or a groom file (.hair .data .tfx .ply)")
    ap.add_argument("--script", help="run a TOML/JSON viewer script (see app/viewer/script.py)")
    ap.add_argument("--size", type=_size, default=(1280, 720), help="window size, e.g. 1280x720")
    ap.add_argument("--glsl-root", help="load shaders from this folder instead of the installed glsl/")
    args = ap.parse_args(argv)
    return run_viewer(args.target, script=args.script, size=args.size, glsl_root=args.glsl_root)


if __name__ == "__main__":
    sys.exit(main())
