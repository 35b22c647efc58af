"""The desktop lookdev viewer: a glfw window, imgui panels over the live GLSL render.

``run_viewer(target, script=..., size=...)`` is the entry point (``vfiber view`` calls it); ``python -m
app.viewer.app [TARGET] [--script FILE] [--size WxH]`` does the same from a shell.

:class:`Viewer` is put together from one part per concern, each in its own module with the state it owns:

    window.py       WindowLoop: glfw/imgui set-up, the frame loop, the render area, input, GL errors
    progressive.py  Progressive: the plan of samples and strips across UI frames, estimates, benches
    loading.py      SceneLoading: scene rebuilds, grooms built in a worker thread, the strand sketch
    hot_reload.py   HotReload: shader files polled, recompiled, swapped only when all compile
    capture.py      Capture: screenshots, grabs, turntables

This module keeps what joins them: the GL objects they share, the commands from the gui or a script
(screenshot, exports, quit) and the entry point.
"""

from __future__ import annotations

from .startup import T_START  # noqa: I001  (first: start-up times count from before the heavy imports)
from .window import WindowLoop  # noqa: I001  (imports imgui_bundle before anything imports glfw)

import argparse
import importlib.util
import sys
import time
from pathlib import Path
from typing import Any

from ..gl.context import GLContextError, create_window
from ..gl.shaders import ProgramCache
from ..params import ParamError
from ..presets import PresetError, find_preset
from ..render.renderer import Renderer
from .capture import Capture
from .compare import CompareView
from .display import ViewportRenderer
from .hot_reload import HotReload
from .loading import SceneLoading, target_is_slow
from .progressive import Progressive
from .script import Script, ScriptError, ScriptRunner, load_script
from .state import AppState, is_groom_path


class Viewer(WindowLoop, Progressive, SceneLoading, HotReload, Capture):
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
        self._init_window(size)
        self._init_progressive()
        self._init_loading()
        self._init_hot_reload()
        self._init_capture()
        self.state.stats.gl_renderer = f"{self.ctx.info['GL_RENDERER']} | {self.ctx.info['GL_VERSION']}"
        try:
            self.state.osl_available = importlib.util.find_spec("app.export.osl") is not None
        except ImportError:
            self.state.osl_available = False
        self._check_gl("startup")
        if target_is_slow(state.params):
            print(f"vfiber view: window up {time.perf_counter() - T_START:.2f} s after start", file=sys.stderr,
                  flush=True)

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


# --- entry point -------------------------------------------------------------------------------------

def initial_state(target: str | None, look: str | None = None) -> AppState:
    """The document the viewer opens with, ``look`` (``--preset``) on it when it is a groom (as
    presets.resolve_params does for every command). Raises PresetError/ParamError for a target it cannot
    use."""
    state = _initial_document(target)
    if look is not None and look != target:
        if not state.on_groom:   # the command line said so already; a caller of the API hears it here
            raise PresetError(f"--preset {look!r} puts a look on a groom, and {target!r} is not one", source=target)
        state.apply_look(find_preset(look))
        state.saved = state.params    # the groom under that look is the document, not an unsaved edit
        state.clear_history()
    return state


def _initial_document(target: str | None) -> AppState:
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
               glsl_root: str | None = None, overrides: dict[str, Any] | None = None,
               look: str | None = None) -> int:
    """Open the viewer on a preset (name or path) or a groom file; returns the process exit code.

    ``script``: a TOML/JSON script (see app/viewer/script.py) run one step per frame; the window stays
    open after it unless it ends with ``quit``. Exit codes: 0 fine, 1 no OpenGL window, 2 a bad target
    or script. ``glsl_root``: shaders from another folder (a copy to experiment in; hot reload follows it).
    ``overrides``: ``--set`` values on top of the target (unsaved changes of the opened document).
    ``look``: a preset whose look goes onto a groom target (``--preset``; see presets.LOOK_GROUPS).
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
        state = initial_state(target, look)
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
