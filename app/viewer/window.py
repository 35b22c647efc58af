"""The window: glfw and imgui set-up, the frame loop, the render area's geometry, input, GL error checks.

One frame::

    events -> script step -> gui(state) (edits values) -> camera controller (edits camera.*)
           -> commands (screenshot, export, quit) -> scene rebuild if scene.* changed
           -> render(state): one fiber sample if the image is out of date -> display -> imgui -> swap

When nothing is out of date the loop sleeps in ``glfw.wait_events_timeout``; the callbacks set in
``_init_imgui`` tell it that an event (not just the timeout) woke it, so an idle viewer draws nothing.
:class:`WindowLoop` is one part of :class:`~app.viewer.app.Viewer`; what it calls of the others (``render``,
``_plan``, ``_update_scene``, ``_poll_shaders``, grabs) lives in their modules.
"""

from __future__ import annotations

# imgui_bundle first: it points pyGLFW at its own libglfw, so both talk to one glfw.
from imgui_bundle import imgui  # noqa: I001  (import order matters, see above)

import ctypes
import math
import statistics
import sys
import time
from collections import deque
from typing import TYPE_CHECKING, Any

from ..render.camera import Camera
from .gui import Layout, gui, refine_overlay
from .navigate import CameraController, Input, make_camera
from .state import now

if TYPE_CHECKING:
    from .script import ScriptRunner

SHADER_POLL_S = 0.5                     # the longest the loop sleeps: hot reload polls the shader files this often
FRAME_HISTORY = 30


class WindowLoop:
    """The glfw window, imgui and the frame loop (a part of ``Viewer``). The loop calls each frame into the
    other parts: ``_poll_shaders`` (hot_reload), ``_update_scene`` (loading), ``_plan``/``render``
    (progressive), ``_save_grab``/``_turntable_step`` (capture)."""

    def _init_window(self, size: tuple[int, int]) -> None:
        self.controller = CameraController()
        self._frame_times: deque[float] = deque(maxlen=FRAME_HISTORY)
        self._ui_times: deque[float] = deque(maxlen=FRAME_HISTORY)   # frame time less its strips
        self._drag_owned = [False, False, False]
        self._script_inputs: list[Input] = []
        self._title = ""
        self._extra_frames = 2
        self._layout = Layout(0, 0, *size)
        self._last_frame = time.perf_counter()
        self.gl_errors: list[str] = []
        self.exit_code: int | None = None

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
        self._sample_started = False
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
        # the UI's own part of a frame, which the strips' budget matches (progressive._budget): every frame
        # but those that began a sample, whose set-up (a sketch, row weights, a first compile: up to seconds
        # once) is not a cost of each frame. Counting only frames with strips made harolongo's median
        # 0.7-1.5 s from its first few frames, so its "30 ms" strips took 120-300 ms a UI frame.
        if not self._sample_started:
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

    # --- errors ------------------------------------------------------------------------------------
    def _check_gl(self, where: str) -> None:
        err = self.ctx.error
        if err != "GL_NO_ERROR":
            self.gl_errors.append(f"{where}: {err}")
            self.state.stats.gl_error = err
            print(f"vfiber view: OpenGL error after {where}: {err}", file=sys.stderr, flush=True)
