"""Scripted viewer sessions: automated lookdev turntables, screenshots and the viewer's own tests.

A script is a TOML or JSON file (by extension; JSON may also be a bare list of steps)::

    size = [640, 360]                        # optional: window size in screen coordinates
    steps = [
      { open = "presets/carpet.toml" },      # preset path or bundled name (discard = true by default;
                                             # discard = false asks, and { answer = ... } replies)
      { bundled = "carpet" },                # File > Open bundled preset; while a groom is on screen a
                                             # preset (open or bundled) is a look on it, File > Apply
                                             # bundled look (whole = true: the whole preset, groom left)
      { revert = true },                     # File > Revert
      { open_groom = "hair/Bangs_100.hair" },    # a groom under the current look (its own camera)
      { set = { "fibers.rings" = 20, "look.color" = [0.8, 0.5, 0.3] } },   # as sliders would
      { wait = 3 },                          # frames shown on screen
      { wait_seconds = 0.5 },
      { wait_final = true },                 # until the full-quality frame (all samples) is shown
      { wait_for = "shader_error", timeout = 30 },    # until a report or stats field is set ("not:x": cleared)
      { screenshot = "out.png", size = [640, 360], view = "shaded" },      # offscreen, no UI
      { grab = "window.png" },               # the window's render area as displayed (no UI)
      { grab = "ui.png", ui = true, final = true },   # the whole window, once the final frame is in
      { save = "look.toml", name = "Look", description = "..." },          # atomic save as
      { export_osl = "look.osl" },           # File > Export OSL (app.export.osl)
      { pin = "A" },                         # Compare > Pin current look (then viewer.compare = "split")
      { render_turntable = "tt", frames = 8, size = [320, 180], alpha = true },   # File > Render turntable
      { view = "heat map" },                 # a debug view (names in state.VIEWS)
      { viewer = { frame_path = "readback", interactive_scale = "25%", show_panel = false } },  # ViewSettings
      { key = "F" },                         # a viewer shortcut (camera keys, 1-7, T)
      { resize = [1024, 600] },              # resize the window (as dragging its edge would)
      { drag = [40, 0], button = "left", shift = false, ctrl = false },   # mouse drag in pixels
      { wheel = 2 },                         # wheel notches (positive zooms in)
      { mouse = [[300, 200, "down"], [360, 200], [360, 200, "up"]], button = "left" },  # real mouse
                                             # events in window coordinates, one per frame, through imgui
      { answer = "discard" },                # reply to an unsaved-changes question
      { turntable = 10, frames = 36, prefix = "tt/f" },  # 36 poses 10 degrees apart; with a prefix
                                             # each final frame is saved as tt/f0000.png, tt/f0001.png...
                                             # (add size = [1920, 1080] to render them offscreen instead)
      { sweep = "look.exposure", values = [0, 0.5, 1], frames = 1 },       # change -> frame latency
      { bench = 10, quality = "final" },     # force 10 renders, print median times ("interactive";
                                             # "ui": frames that draw the UI and the last image only;
                                             # "refining": the next 10 UI frames that draw strips of a
                                             # slow frame, refining as it would without a bench)
      { print = "last_error" },              # one JSON line on stdout: a report field, or "report"
      { report = "state.json" },             # the whole report as a file
      { render_anyway = true },              # the panel's "Render anyway": start a slow look's final frame
      { echo = "text" },
      { quit = 0 },                          # exit code; a script without quit leaves the window open
    ]

The first key of a step is its action, the others its options. Each printed line starts with
``vfiber-script: `` followed by JSON, so a caller can pick them out of the output. A step that cannot
run stops the script with exit code 2 and a message naming the step.
"""

from __future__ import annotations

import json
import statistics
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import VfiberError
from .navigate import Input
from .state import VIEWS

if TYPE_CHECKING:
    from .host import ViewerHost

PREFIX = "vfiber-script: "
ACTIONS = ("open", "set", "wait", "wait_final", "screenshot", "grab", "save", "view", "key", "drag",
           "wheel", "answer", "turntable", "sweep", "bench", "print", "report", "echo", "quit", "revert",
           "bundled", "open_groom", "wait_seconds", "viewer", "wait_for", "resize", "mouse", "export_osl", "pin",
           "render_turntable", "render_anyway")
OPTIONS = {"size", "view", "name", "description", "button", "shift", "ctrl", "frames", "values",
           "quality", "discard", "prefix", "timeout", "final", "ui", "alpha", "whole"}
WAIT_FINAL_TIMEOUT_S = 300.0


class ScriptError(VfiberError, ValueError):
    """A viewer script that cannot run: the message names the script's step and what it expects."""


@dataclass
class Script:
    steps: list[dict[str, Any]]
    size: tuple[int, int] | None = None
    source: str = "<script>"


def load_script(path: str | Path) -> Script:
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise ScriptError(f"{path}: cannot read the script: {e.strerror or e}") from None
    try:
        doc = json.loads(text) if path.suffix.lower() == ".json" else tomllib.loads(text)
    except (json.JSONDecodeError, tomllib.TOMLDecodeError) as e:
        raise ScriptError(f"{path}: not valid {'JSON' if path.suffix.lower() == '.json' else 'TOML'}: {e}") from None
    return parse_script(doc, str(path))


def parse_script(doc: Any, source: str = "<script>") -> Script:
    if isinstance(doc, list):
        doc = {"steps": doc}
    if not isinstance(doc, dict) or not isinstance(doc.get("steps"), list):
        raise ScriptError(f"{source}: expected a 'steps' list (steps = [ {{ set = {{...}} }}, ... ])")
    unknown = set(doc) - {"steps", "size"}
    if unknown:
        raise ScriptError(f"{source}: unknown top-level key {sorted(unknown)[0]!r}; allowed: steps, size")
    size = doc.get("size")
    if size is not None and not (isinstance(size, list) and len(size) == 2
                                 and all(isinstance(x, int) and x > 0 for x in size)):
        raise ScriptError(f"{source}: size = {size!r} should be [width, height] in pixels")
    steps = []
    for i, step in enumerate(doc["steps"], 1):
        if not isinstance(step, dict):
            raise ScriptError(f"{source}: step {i} = {step!r} should be a table like {{ wait = 3 }}")
        action = next(iter(step), None)   # the first key is the action, the rest are its options
        if action not in ACTIONS:
            raise ScriptError(f"{source}: step {i} {step!r} should start with an action, one of: "
                              f"{', '.join(ACTIONS)}")
        extra = set(step) - {action} - OPTIONS
        if extra:
            raise ScriptError(f"{source}: step {i}: unknown option {sorted(extra)[0]!r}; options: "
                              f"{', '.join(sorted(OPTIONS))}")
        steps.append(step)
    return Script(steps, tuple(size) if size else None, source)


def set_view_setting(view: Any, name: str, value: Any) -> None:
    """One ViewSettings field, checked against its type and, where there is one, its list of choices."""
    from dataclasses import fields as dc_fields
    from .compare import MODES as COMPARE_MODES
    from .state import FRAME_PATHS, INTERACTIVE_MODES, INTERACTIVE_SCALES, TURNTABLE_TURNS

    known = {f.name: f for f in dc_fields(view)}
    if name not in known:
        raise ScriptError(f"viewer setting {name!r} does not exist; settings: {', '.join(known)}")
    choices = {"view": VIEWS, "interactive_scale": INTERACTIVE_SCALES, "interactive_mode": INTERACTIVE_MODES,
               "frame_path": FRAME_PATHS, "compare": COMPARE_MODES, "turntable_turns": TURNTABLE_TURNS}.get(name)
    current = getattr(view, name)
    if choices is not None and value not in choices:
        raise ScriptError(f"viewer {name} = {value!r}: one of {', '.join(choices)}")
    if isinstance(current, bool) and not isinstance(value, bool):
        raise ScriptError(f"viewer {name} = {value!r}: true or false")
    if isinstance(current, float) and (isinstance(value, bool) or not isinstance(value, (int, float))):
        raise ScriptError(f"viewer {name} = {value!r}: a number")
    setattr(view, name, float(value) if isinstance(current, float) else value)


def emit(**fields: Any) -> None:
    print(PREFIX + json.dumps(fields, default=str), flush=True)


@dataclass
class ScriptRunner:
    """Runs one step per frame (waits take several); the viewer calls ``tick`` before each frame's gui."""

    script: Script
    index: int = 0
    exit_code: int | None = None        # set when the script quits (or fails)
    _wait_frames: int = 0
    _wait_until: float = 0.0
    _wait_final_since: float | None = None
    _wait_for: tuple[str, float] | None = None   # (report field, deadline)
    _loop: dict[str, Any] | None = None  # a running multi-frame step (turntable, sweep, bench)
    inputs: list[Input] = field(default_factory=list)

    @property
    def done(self) -> bool:
        return self.index >= len(self.script.steps) and self._loop is None

    def tick(self, viewer: ViewerHost) -> None:
        """Called at the start of a frame. Runs steps until one needs frames to pass."""
        if self.exit_code is not None or viewer.loading():
            return           # a scene being built: its steps would act on the one before
        if self._wait_frames > 0:
            self._wait_frames -= 1
            return
        if self._wait_until and time.perf_counter() < self._wait_until:
            return
        self._wait_until = 0.0
        if self._wait_final_since is not None:
            if viewer.final_shown():
                self._wait_final_since = None
            elif time.perf_counter() - self._wait_final_since > WAIT_FINAL_TIMEOUT_S:
                self._fail(viewer, f"wait_final: no final frame after {WAIT_FINAL_TIMEOUT_S:.0f} s")
                return
            else:
                return
        if self._wait_for is not None:
            name, deadline = self._wait_for
            negate = name.startswith("not:")
            report = viewer.state.report()
            field_name = name.removeprefix("not:")
            value = bool(report[field_name] if field_name in report else report["stats"].get(field_name))
            if value != negate:
                self._wait_for = None
            elif time.perf_counter() > deadline:
                self._wait_for = None
                self._fail(viewer, f"wait_for {name!r}: still not so after the timeout")
                return
            else:
                return
        if self._loop is not None:
            self._continue_loop(viewer)
            return
        while self.index < len(self.script.steps) and self.exit_code is None:
            step = self.script.steps[self.index]
            self.index += 1
            try:
                waits = self._run(viewer, step)
            except Exception as e:  # a bad step stops the script with its number and the reason
                self._fail(viewer, f"{type(e).__name__}: {e}", step)
                return
            if waits:
                return

    def _fail(self, viewer: ViewerHost, message: str, step: dict[str, Any] | None = None) -> None:
        import sys
        where = f"step {self.index} {json.dumps(step, default=str)}" if step is not None else f"step {self.index}"
        print(f"vfiber view: script {self.script.source}: {where}: {message}", file=sys.stderr, flush=True)
        self.exit_code = 2

    def _run(self, viewer: ViewerHost, step: dict[str, Any]) -> bool:
        """Run one step; True when the script must wait for frames before the next."""
        state = viewer.state
        action = next(iter(step))
        arg = step[action]
        if action == "set":
            if not isinstance(arg, dict):
                raise ScriptError("set = { key = value, ... }")
            state.begin_gesture()
            state.edit_many(arg)
            state.end_gesture()
        elif action == "open":
            state.open(str(arg), discard=step.get("discard", True), whole=bool(step.get("whole")))
        elif action == "open_groom":
            state.open_groom(str(arg))
        elif action == "bundled":
            state.open(str(arg), discard=step.get("discard", True), whole=bool(step.get("whole")))
        elif action == "revert":
            state.revert(discard=step.get("discard", True))
        elif action == "answer":
            if arg not in ("discard", "save", "cancel"):
                raise ScriptError("answer = 'discard' | 'save' | 'cancel'")
            state.answer_confirm(arg)
        elif action == "save":
            if not state.save_as(str(arg), step.get("name"), step.get("description")):
                raise ScriptError(f"save failed: {state.last_error}")
        elif action == "export_osl":
            if not viewer.export_osl(str(arg)):
                raise ScriptError(f"export_osl failed: {state.last_error}")
            emit(export_osl=str(arg))
        elif action == "wait":
            self._wait_frames = int(arg)
            return self._wait_frames > 0
        elif action == "wait_seconds":
            self._wait_until = time.perf_counter() + float(arg)
            return True
        elif action == "wait_final":
            self._wait_final_since = time.perf_counter()
            return True
        elif action == "wait_for":
            field_name = str(arg).removeprefix("not:")
            report = viewer.state.report()
            if field_name not in report and field_name not in report["stats"]:
                raise ScriptError(f"wait_for = {arg!r}: a report or stats field ({', '.join(report)}, "
                                  f"{', '.join(report['stats'])})")
            self._wait_for = (str(arg), time.perf_counter() + float(step.get("timeout", 60)))
            return True
        elif action == "screenshot":
            size = step.get("size")
            viewer.screenshot(str(arg), tuple(size) if size else None, step.get("view", "shaded"))
            emit(screenshot=str(arg))
        elif action == "grab":
            viewer.request_grab(str(arg), bool(step.get("final", False)), bool(step.get("ui", False)))
            return True  # the grab happens when this frame is displayed
        elif action == "view":
            if arg not in VIEWS:
                raise ScriptError(f"view = {arg!r}: one of {', '.join(VIEWS)}")
            state.view.view = arg
            state.touch()
        elif action == "viewer":
            if not isinstance(arg, dict):
                raise ScriptError("viewer = { setting = value, ... } (fields of state.ViewSettings)")
            for name, value in arg.items():
                set_view_setting(state.view, name, value)
            state.touch()
        elif action == "resize":
            if not (isinstance(arg, list) and len(arg) == 2 and all(isinstance(x, int) and x > 0 for x in arg)):
                raise ScriptError("resize = [width, height]")
            viewer.resize_window(*arg)
            return True   # the new size arrives with the next frame's events
        elif action == "key":
            viewer.script_input(Input(keys={str(arg).upper()}))
        elif action == "drag":
            button = step.get("button", "left")
            inp = Input(dx=float(arg[0]), dy=float(arg[1]), shift=bool(step.get("shift")),
                        ctrl=bool(step.get("ctrl")), **{button: True})
            viewer.script_input(inp)
        elif action == "wheel":
            viewer.script_input(Input(wheel=float(arg)))
        elif action == "mouse":
            events = [list(e) for e in arg]
            if not events or not all(len(e) in (2, 3) for e in events):
                raise ScriptError('mouse = [[x, y], [x, y, "down"|"up"], ...]')
            button = {"left": 0, "right": 1, "middle": 2}[step.get("button", "left")]
            self._loop = {"kind": "mouse", "events": events, "button": button}
            self._continue_loop(viewer)
            return True
        elif action == "turntable":
            self._loop = {"kind": "turntable", "step": float(arg), "frames": int(step.get("frames", 36)),
                          "n": 0, "prefix": step.get("prefix"), "phase": "pose", "size": step.get("size"),
                          "start": state.params["camera.azimuth"]}
            self._continue_loop(viewer)
            return True
        elif action == "sweep":
            values = list(step.get("values") or [])
            if not values:
                raise ScriptError("sweep needs values = [...]")
            self._loop = {"kind": "sweep", "key": str(arg), "values": values, "frames": int(step.get("frames", 1)),
                          "lat": [], "wait": 0}
            self._continue_loop(viewer)
            return True
        elif action == "bench":
            quality = step.get("quality", "final")
            if quality not in ("final", "interactive", "ui", "refining"):
                raise ScriptError("bench quality = 'final' | 'interactive' | 'ui' (frames without a fiber render)"
                                  " | 'refining' (UI frames while a slow frame is drawn in strips)")
            viewer.bench_begin(quality)
            self._loop = {"kind": "bench", "left": int(arg), "quality": quality,
                          "until": time.perf_counter() + float(step.get("timeout", 120))}
            return True
        elif action == "print":
            report = state.report()
            if arg == "gl_error":          # every GL error seen this session (an empty list: none)
                emit(gl_error=viewer.gl_errors)
            elif arg == "report":
                emit(report=report)
            elif arg in report:
                emit(**{arg: report[arg]})
            elif arg in report["stats"]:
                emit(**{arg: report["stats"][arg]})
            else:
                raise ScriptError(f"print = {arg!r}: a report field ({', '.join(report)}), a stats field, "
                                  "'gl_error' or 'report'")
        elif action == "report":
            report = state.report()
            report["gl_errors"] = viewer.gl_errors
            Path(str(arg)).write_text(json.dumps(report, indent=2, default=str), encoding="utf-8")
        elif action == "pin":                  # Compare > Pin current look (A); arg: its name, or true
            state.pin(arg if isinstance(arg, str) else None)
        elif action == "render_turntable":     # File > Render turntable: frames into the folder arg
            viewer.state.request("turntable", path=str(arg), frames=int(step.get("frames", 36)),
                                 size=tuple(step.get("size") or (640, 360)), alpha=bool(step.get("alpha")))
        elif action == "render_anyway":        # the panel's "Render anyway": the slow look's final frame
            state.render_anyway()
        elif action == "echo":
            emit(echo=str(arg))
        elif action == "quit":
            self.exit_code = int(arg) if not isinstance(arg, bool) else 0
            return True
        return False

    def _continue_loop(self, viewer: ViewerHost) -> None:
        loop = self._loop
        assert loop is not None
        state = viewer.state
        if loop["kind"] == "mouse":
            if not loop["events"]:
                self._loop = None
                return
            viewer.mouse_event(loop["events"].pop(0), loop["button"])
        elif loop["kind"] == "turntable":
            # pose -> (wait for the final frame -> grab) -> next pose; frame n is at start + n * step
            if viewer.grab_pending():
                return
            if loop["phase"] == "next":
                loop["n"] += 1
                loop["phase"] = "pose"
            if loop["phase"] == "pose":
                if loop["n"] >= loop["frames"]:
                    self._loop = None
                    return
                az = loop["start"] + loop["n"] * loop["step"]
                state.set_camera(azimuth=(az + 180.0) % 360.0 - 180.0)
                if loop["prefix"]:
                    loop["phase"] = "shot"
                    if not loop["size"]:   # a grab of the window: wait until the final frame is in
                        self._wait_final_since = time.perf_counter()
                else:
                    loop["phase"] = "next"
            elif loop["phase"] == "shot":
                path = f"{loop['prefix']}{loop['n']:04d}.png"
                if loop["size"]:           # offscreen at the given size, final quality, no UI
                    viewer.screenshot(path, tuple(loop["size"]), "shaded")
                    emit(screenshot=path)
                else:
                    viewer.request_grab(path, final=True)
                loop["phase"] = "next"
        elif loop["kind"] == "sweep":
            if loop["wait"] > 0:
                loop["wait"] -= 1
                if loop["wait"] == 0 and state.stats.edit_latency_ms is not None:
                    loop["lat"].append(state.stats.edit_latency_ms)
                return
            if not loop["values"]:
                lat = loop["lat"]
                emit(sweep=loop["key"], latency_ms=lat, median_ms=statistics.median(lat) if lat else None)
                self._loop = None
                return
            state.stats.edit_latency_ms = None
            state.begin_gesture()
            state.edit(loop["key"], loop["values"].pop(0))
            loop["wait"] = loop["frames"]
        elif loop["kind"] == "bench":
            if loop["quality"] == "refining":   # counts frames that refined; gives up after the timeout
                if viewer.bench_frames() >= loop["left"] or time.perf_counter() > loop["until"]:
                    emit(bench=viewer.bench_end())
                    self._loop = None
                return
            if loop["left"] <= 0:
                emit(bench=viewer.bench_end())
                self._loop = None
                return
            loop["left"] -= 1
