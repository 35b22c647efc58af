"""The viewer's state: every value the panels edit, with no imgui and no OpenGL in sight.

``gui(state)`` (gui.py) only changes these values; ``Viewer.render`` (app.py) only reads them. The
script runner (script.py) drives the same methods the panels call, so a scripted session and a person at
the keyboard go down one path.

Editing rules that an artist sees:

* ``edit(key, value)`` validates through ``Params``; a value that breaks a relation between parameters
  (e.g. ``scene.generator = 'groom'`` without a file) is kept as *pending* beside the field with the
  ``ParamError`` message, and the last valid parameters keep rendering. Fixing the other field applies it.
* Changing ``fibers.rings`` clamps ``fibers.fiber_radius`` to ``0.5 / rings`` (a fiber must fit its ring)
  and leaves a note beside the field saying so.
* Camera moves are saved with the preset but do not mark it modified (as in Blender, where orbiting the
  viewport never asks "save changes?"); everything else does.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..params import BY_KEY, SPEC, ParamError, Params, max_fiber_radius, suggest
from ..presets import (LOOK_GROUPS, Preset, PresetError, apply_look, find_preset, is_groom, load_preset,
                       look_values, save_preset)
# the explicit baseline's own allocation, so the viewer and `vfiber info` show one figure
from ..render.explicit import EXPLICIT_FORMULA, explicit_bytes  # noqa: F401 - the viewer's names for them
from ..scene.grooms import GROOM_SUFFIXES

VIEWS: tuple[str, ...] = ("shaded", "fiber ids", "rings", "normals", "depth", "heat map", "proxies")
INTERACTIVE_SCALES: tuple[str, ...] = ("25%", "50%", "75%", "100%", "auto")
INTERACTIVE_MODES: tuple[str, ...] = ("fast", "final mode")
FRAME_PATHS: tuple[str, ...] = ("direct", "readback")
TURNTABLE_TURNS: tuple[str, ...] = ("camera", "lights")
UNDO_DEPTH = 200


def now() -> float:
    return time.perf_counter()


@dataclass
class ViewSettings:
    """Viewer-only settings: never saved in a preset."""

    view: str = "shaded"                 # one of VIEWS
    interactive_scale: str = "50%"       # one of INTERACTIVE_SCALES: resolution while dragging
    interactive_mode: str = "fast"       # "fast" (thesis order, first hit) or "final mode" (quality.mode)
    auto_budget_ms: float = 120.0        # "auto" scale aims the interactive render at this time
    refine_delay: float = 0.3            # seconds of stillness before the final frame
    refine_budget_ms: float = 30.0       # fiber time per UI frame while a slow frame refines in strips
    frame_path: str = "direct"           # "direct": draw from the renderer's texture; "readback": via numpy
    heat_max: float = 0.0                # heat-map top of scale, fiber tests; 0 = automatic (99th percentile)
    turntable: bool = False
    turntable_speed: float = 30.0        # degrees per second
    turntable_turns: str = "camera"      # one of TURNTABLE_TURNS: what the turntable turns
    show_panel: bool = True
    show_stats: bool = True
    show_help: bool = False
    show_stats_details: bool = False     # the stats overlay's numbers for developers (cost, GPU, thesis count)
    compare: str = "off"                 # one of compare.MODES: A/B against the pinned look
    compare_split: float = 0.5           # where A ends, as a fraction of the render's width
    panel_width: float = 380.0           # points (logical pixels); scaled by the monitor's content scale


@dataclass
class Confirm:
    """A question waiting for the person: discard unsaved changes before ``action``?"""

    message: str
    action: Callable[[], Any]
    can_save: bool = True


@dataclass
class Stats:
    """Numbers the overlay shows; filled by the app, read by the gui."""

    frame_ms: float = 0.0                # median loop time over the last frames
    render_ms: float = 0.0               # last fiber render: GPU timer query (or wall clock past 4.29 s)
    render_clock: str = "gpu"            # "gpu" or "wall"
    render_size: tuple[int, int] = (0, 0)
    label: str = ""                      # what is on screen: "interactive 50% fast" / "final exact"
    samples: tuple[int, int] = (0, 0)    # (accumulated, wanted) supersamples of the final frame
    fibers_41: float = 0.0               # thesis expression 4.1 over the scene's guides
    fibers_exact: int = 0
    guides: int = 0
    segments: int = 0
    scene_gpu_bytes: int = 0
    frame_gpu_bytes: int | None = None   # the renderer's per-pixel buffers (None: it does not count them)
    viewer_gpu_bytes: int = 0            # the viewer's own: accumulation, uploads, base pictures
    refining: float | None = None        # fraction of the final picture drawn while it refines in strips
    drawing: str = ""                    # the quality of the sample being drawn in strips ("final" or
                                         # "interactive"; "" when none is)
    explicit_bytes: int = 0              # explicit storage of the same fibers (see EXPLICIT_FORMULA)
    tests_per_pixel: float | None = None  # mean fiber tests per container-covered pixel (cost render)
    tests_p99: float = 0.0
    covered_pixels: int = 0
    cost_size: tuple[int, int] = (0, 0)
    cost_age_s: float = 0.0
    edit_latency_ms: float | None = None  # slider change -> the frame that shows it, on screen
    scene_build_ms: float = 0.0
    depth_range: tuple[float, float] = (0.0, 1.0)   # what the depth view maps white .. black
    estimate: str = ""                   # the final frame's cost in plain words, when it takes seconds or more
    estimate_slow: bool = False          # ... past budget.SLOW_SECONDS: the final frame waits for "Render anyway"
    estimate_seconds: float = 0.0
    gl_renderer: str = ""
    gl_error: str = "GL_NO_ERROR"


@dataclass
class AppState:
    params: Params = field(default_factory=Params)
    saved: Params | None = None          # what the preset file holds (None: never saved)
    preset_path: Path | None = None
    preset_name: str = ""
    preset_description: str = ""
    look_name: str = ""                  # the preset whose look was last put on the groom (File > Apply look)
    view: ViewSettings = field(default_factory=ViewSettings)
    stats: Stats = field(default_factory=Stats)

    pending: dict[str, Any] = field(default_factory=dict)   # values shown in a field but not valid yet
    errors: dict[str, str] = field(default_factory=dict)    # key -> ParamError message, shown inline
    notes: dict[str, str] = field(default_factory=dict)     # key -> an explanation (e.g. a clamp)
    last_error: str | None = None        # the error dialog's text; None when closed
    last_error_key: str | None = None
    error_log: list[str] = field(default_factory=list)      # every error shown this session
    status: str = ""                     # one-line message in the status bar
    confirm: Confirm | None = None
    scene_error: str | None = None       # the scene could not be built from the current parameters
    shader_error: str | None = None      # a hot reload failed; the last good program stays on screen
    osl_available: bool = False
    pinned: Params | None = None         # look A of an A/B comparison (Compare > Pin current look)
    pinned_name: str = ""
    slow_confirmed: bool = False         # "Render anyway" for the slow look on screen; the app clears it when
                                         # the look changes (camera moves and window sizes keep it)

    last_change: float = 0.0             # perf_counter of the last change to what is rendered
    last_edit: float | None = None       # perf_counter of the last parameter edit not yet on screen
    dragging: bool = False               # a slider (or a camera drag) is held this frame
    commands: list[tuple[str, dict[str, Any]]] = field(default_factory=list)  # for the app: screenshot...
    scratch: dict[str, Any] = field(default_factory=dict)   # the gui's typed-but-unapplied text, dialogs

    _undo: list[Params] = field(default_factory=list)
    _redo: list[Params] = field(default_factory=list)
    _gesture_open: bool = False

    # --- what is shown -----------------------------------------------------------------------------
    @property
    def dirty(self) -> bool:
        """Unsaved changes, camera excluded (see the module docstring)."""
        base = self.saved if self.saved is not None else Params()
        return any(self.params[k] != base[k] for k in self.params if not k.startswith("camera."))

    @property
    def display_name(self) -> str:
        if self.preset_name:
            return self.preset_name
        return self.preset_path.stem if self.preset_path else "untitled"

    @property
    def title(self) -> str:
        star = "*" if self.dirty else ""
        where = f" ({self.preset_path})" if self.preset_path else ""
        return f"{self.display_name}{star}{where} - vfiber"

    def value(self, key: str) -> Any:
        """What a field shows: a pending (not yet valid) value, else the live one."""
        return self.pending.get(key, self.params[key])

    @property
    def final_held(self) -> bool:
        """The final frame of a slow look waits for the person (the interactive preview still draws)."""
        return self.stats.estimate_slow and not self.slow_confirmed

    def render_anyway(self) -> None:
        """The panel's "Render anyway": start the final frame of the slow look on screen."""
        self.slow_confirmed = True
        self.touch()

    def touch(self) -> None:
        """Something that changes the image happened: show interactive quality for a moment."""
        self.last_change = now()

    # --- editing -----------------------------------------------------------------------------------
    def begin_gesture(self) -> None:
        """Start of one undoable step (a slider press, a script ``set``)."""
        self._gesture_open = False

    def end_gesture(self) -> None:
        self._gesture_open = False

    def _push_undo(self) -> None:
        if not self._gesture_open:
            if not self._undo or self._undo[-1] != self.params:
                self._undo.append(self.params)
                del self._undo[:-UNDO_DEPTH]
            self._redo.clear()
            self._gesture_open = True

    def edit(self, key: str, value: Any, *, undoable: bool = True) -> bool:
        """Set one parameter as a slider would. Returns True when the rendered parameters changed."""
        return self.edit_many({key: value}, undoable=undoable)

    def edit_many(self, changes: dict[str, Any], *, undoable: bool = True) -> bool:
        for key in changes:
            if key not in BY_KEY:
                raise ParamError(f"unknown parameter {key!r}{suggest(key)}", key=key, source="viewer")
        # each value alone must be allowed; a bad one stays in its field with the reason
        accepted: dict[str, Any] = {}
        for key, value in changes.items():
            try:
                accepted[key] = BY_KEY[key].check(value)
            except ParamError as e:
                self.pending[key] = value
                self.errors[key] = e.bare
        if not accepted:
            return False
        for key in accepted:
            self.pending.pop(key, None)
            self.errors.pop(key, None)
        if "fibers.fiber_radius" in accepted:
            self.notes.pop("fibers.fiber_radius", None)
        # values waiting only for another field (a relation) are tried again with this edit
        waiting = {k: BY_KEY[k].check(v) for k, v in self.pending.items() if _valid_alone(k, v)}
        result = self._try({**self.params.values, **waiting, **accepted}, accepted)
        if result is not None:
            for key in waiting:
                self.pending.pop(key, None)
                self.errors.pop(key, None)
        else:  # without the waiting values: this edit may be fine on its own
            result = self._try({**self.params.values, **accepted}, accepted)
        if result is None:
            if len(accepted) > 1:  # several keys at once (a script): let the independent ones through
                changed = False
                for key, value in accepted.items():
                    changed |= self.edit_many({key: value}, undoable=undoable)
                return changed
            error = self._relation_error({**self.params.values, **accepted}, accepted)
            for key, value in accepted.items():
                self.pending[key] = value
                self.errors[key] = error.bare
            if error.key in self.pending:
                self.errors[error.key] = error.bare
            return False
        new, note = result
        new = _with_groom_defaults(self.params, new, accepted)
        if note:
            self.notes["fibers.fiber_radius"] = note
            self.pending.pop("fibers.fiber_radius", None)
            self.errors.pop("fibers.fiber_radius", None)
        if new == self.params:
            return False
        if undoable:
            self._push_undo()
        self._set_params(new, edited=True)
        return True

    def _try(self, candidate: dict[str, Any], accepted: dict[str, Any]) -> tuple[Params, str] | None:
        candidate, note = _clamped(candidate, accepted)
        try:
            return Params(candidate), note
        except ParamError:
            return None

    @staticmethod
    def _relation_error(candidate: dict[str, Any], accepted: dict[str, Any]) -> ParamError:
        try:
            Params(_clamped(candidate, accepted)[0])
        except ParamError as e:
            return e
        return ParamError("these values do not work together")

    def _set_params(self, new: Params, *, edited: bool) -> None:
        self.params = new
        self.touch()
        if edited:
            self.last_edit = now()

    def reset_key(self, key: str) -> bool:
        """Back to the SPEC default (right-click > Reset to default)."""
        return self.edit(key, BY_KEY[key].default)

    # --- undo --------------------------------------------------------------------------------------
    def undo(self) -> bool:
        if not self._undo:
            self.status = "nothing to undo"
            return False
        self._redo.append(self.params)
        self._replace_all(self._undo.pop())
        self.status = "undo"
        return True

    def redo(self) -> bool:
        if not self._redo:
            self.status = "nothing to redo"
            return False
        self._undo.append(self.params)
        self._replace_all(self._redo.pop())
        self.status = "redo"
        return True

    def _replace_all(self, params: Params) -> None:
        self.pending.clear()
        self.errors.clear()
        self.notes.clear()
        self._gesture_open = False
        self._set_params(params, edited=True)

    def clear_history(self) -> None:
        self._undo.clear()
        self._redo.clear()
        self._gesture_open = False

    # --- camera ------------------------------------------------------------------------------------
    def set_camera(self, **values: Any) -> None:
        """Navigation: camera.* without an undo step and without the unsaved-changes mark."""
        self.edit_many({f"camera.{k}": v for k, v in values.items()}, undoable=False)

    def frame_all(self) -> None:
        self.set_camera(target=(0.0, 0.0, 0.0), distance=0.0)
        self.status = "framed the whole scene"

    def reset_camera(self) -> None:
        base = self.saved if self.saved is not None else Params()
        self.set_camera(**{k.split(".", 1)[1]: base[k] for k in base if k.startswith("camera.")})
        self.status = "camera reset to the preset's"

    # --- A/B comparison ----------------------------------------------------------------------------
    def pin(self, name: str | None = None) -> None:
        """Keep the current look as A; what you change next is B. Turns the split view on."""
        self.pinned = self.params
        self.pinned_name = name or f"{self.display_name}{'*' if self.dirty else ''}"
        if self.view.compare == "off":
            self.view.compare = "split"
        self.status = f"pinned {self.pinned_name} as A: changes now show as B, right of the line"
        self.touch()

    def unpin(self) -> None:
        self.pinned = None
        self.pinned_name = ""
        self.view.compare = "off"
        self.touch()

    # --- errors ------------------------------------------------------------------------------------
    def show_error(self, message: str, key: str | None = None) -> None:
        self.last_error = message
        self.last_error_key = key
        self.error_log.append(message)
        self.status = "error: " + message.splitlines()[0]

    def close_error(self) -> None:
        self.last_error = None
        self.last_error_key = None

    # --- presets -----------------------------------------------------------------------------------
    def guard(self, what: str, action: Callable[[], Any], discard: bool) -> bool:
        """Run ``action`` now, or ask first when it would throw away unsaved changes. False when it asked
        or when the action returned False (it failed and said why)."""
        if self.dirty and not discard:
            self.confirm = Confirm(f"{self.display_name} has unsaved changes. {what} anyway?", action)
            return False
        return action() is not False

    def answer_confirm(self, answer: str) -> None:
        """``discard``: go ahead; ``save``: save, then go ahead; ``cancel``: keep everything."""
        pending, self.confirm = self.confirm, None
        if pending is None or answer == "cancel":
            self.status = "cancelled" if pending else self.status
            return
        if answer == "save" and not self.save():
            return  # saving failed (no path, or an error dialog): do not discard
        pending.action()

    @property
    def on_groom(self) -> bool:
        """A groom's strands are on screen (a groom file, or a preset holding one)."""
        return is_groom(self.params)

    def open(self, target: str | os.PathLike[str], *, discard: bool = False, whole: bool = False) -> bool:
        """Open a preset file (or a bundled preset by name). Asks before discarding changes. While a groom is
        on screen a preset without a groom of its own is a look: it goes onto the groom (``apply_look``), the
        groom's strands and camera stay; ``whole`` opens it as its own scene instead."""
        if self.on_groom and not whole:
            try:
                preset = find_preset(target)
            except PresetError as e:
                self.show_error(str(e), e.key)
                return False
            if not is_groom(preset.params):
                return self.apply_look(preset)
        return self.guard(f"Open {target}", lambda: self._open_now(target), discard)

    def apply_look(self, preset: Preset) -> bool:
        """The preset's look (presets.LOOK_GROUPS: fibers, shape, look, light) on what is on screen, as one
        undoable edit; the scene, camera and quality stay, so the groom neither moves nor changes."""
        new = apply_look(self.params, preset.params)
        for key in [k for k in (*self.pending, *self.errors, *self.notes) if k.split(".", 1)[0] in LOOK_GROUPS]:
            self.pending.pop(key, None)
            self.errors.pop(key, None)
            self.notes.pop(key, None)
        self.look_name = preset.name or (Path(preset.path).stem if preset.path else "")
        self.status = (f"the look of {self.look_name} on {self.display_name}: its fibers, shape, look and light; "
                       "the strands, camera and quality stay")
        if new == self.params:
            return True
        self.begin_gesture()
        self._push_undo()
        self.end_gesture()
        self._set_params(new, edited=True)
        return True

    def _open_now(self, target: str | os.PathLike[str]) -> bool:
        try:
            preset = find_preset(target)
        except PresetError as e:  # the scene is untouched: params stay what they were
            self.show_error(str(e), e.key)
            return False
        self.adopt(preset)
        self.status = f"opened {preset.path or target}"
        return True

    def adopt(self, preset: Preset) -> None:
        """Make a loaded preset the current document."""
        self.pending.clear()
        self.errors.clear()
        self.notes.clear()
        self._undo.clear()
        self._redo.clear()
        self.saved = preset.params
        self.preset_path = Path(preset.path) if preset.path else None
        self.preset_name = preset.name
        self.preset_description = preset.description
        self.look_name = ""
        self._set_params(preset.params, edited=True)

    def open_groom(self, path: str | os.PathLike[str]) -> bool:
        """Put a groom file's strands under the current look, as one undoable edit: the groom's own scene,
        camera (framing it) and quality with the look on screen (``apply_look``), so ``vfiber view GROOM
        --preset LOOK`` and opening GROOM while LOOK is on screen show the same."""
        absolute = str(Path(path).expanduser().resolve())
        if not Path(absolute).is_file():
            self.show_error(f"no groom file {str(path)!r}", "scene.groom_file")
            return False
        new = apply_look(Params({"scene.generator": "groom", "scene.groom_file": absolute}), self.params)
        # fibers.groom_auto as `vfiber view GROOM --preset LOOK` applies it: the look's keys are given, so only
        # the groom's scene keys (its interpolated children) take the groom's values
        new = _with_groom_defaults(self.params, new, look_values(self.params))
        for key in [k for k in (*self.pending, *self.errors) if k.split(".", 1)[0] not in LOOK_GROUPS]:
            self.pending.pop(key, None)   # a half-typed scene value belonged to the scene that goes
            self.errors.pop(key, None)
        self.status = f"groom {Path(path).name}"
        if new != self.params:
            self.begin_gesture()
            self._push_undo()
            self.end_gesture()
            self._set_params(new, edited=True)
        return True

    def save(self) -> bool:
        """Save to the current file; without one, ask for a path (the gui opens Save As). So does a document
        whose scene now comes from elsewhere (a groom opened onto a look preset): saving it in place would
        replace the person's look file with a groom scene."""
        if self.preset_path is None or self._scene_source_changed():
            self.commands.append(("ask_save_as", {}))
            return False
        return self.save_as(self.preset_path)

    def _scene_source_changed(self) -> bool:
        if self.saved is None:
            return False
        return any(self.params[k] != self.saved[k] for k in ("scene.generator", "scene.groom_file"))

    def save_as(self, path: str | os.PathLike[str], name: str | None = None,
                description: str | None = None) -> bool:
        path = Path(path)
        if path.suffix == "":
            path = path.with_suffix(".toml")
        name = self.preset_name if name is None else name
        description = self.preset_description if description is None else description
        try:
            save_preset(path, self.params, name, description)  # atomic: temp file + rename
        except (OSError, TypeError, ValueError) as e:
            self.show_error(f"{path}: could not save the preset: {getattr(e, 'strerror', None) or e}")
            return False
        self.saved = self.params
        self.preset_path = path
        self.preset_name, self.preset_description = name, description
        self.status = f"saved {path}"
        return True

    def revert(self, *, discard: bool = False) -> bool:
        """Back to the file on disk (re-read, so edits made elsewhere show up)."""
        if self.preset_path is None and self.saved is None:
            return self.guard("Revert to defaults", lambda: self.adopt(Preset("", "", Params())), discard)

        def go() -> bool:
            if self.preset_path is not None:
                try:
                    preset = load_preset(self.preset_path)
                except PresetError as e:
                    self.show_error(str(e), e.key)
                    return False
            else:
                preset = Preset(self.preset_name, self.preset_description, self.saved or Params())
            self.adopt(preset)
            self.status = "reverted"
            return True
        return self.guard("Revert", go, discard)

    def request(self, command: str, **args: Any) -> None:
        """Ask the app for something that needs the GPU or the window (screenshot, export, quit)."""
        self.commands.append((command, args))

    # --- for scripts and tests ----------------------------------------------------------------------
    def report(self) -> dict[str, Any]:
        s = self.stats
        return {
            "title": self.title, "dirty": self.dirty, "preset_path": str(self.preset_path or ""),
            "last_error": self.last_error, "last_error_key": self.last_error_key,
            "errors": dict(self.errors), "pending": {k: _jsonable(v) for k, v in self.pending.items()},
            "notes": dict(self.notes), "scene_error": self.scene_error, "shader_error": self.shader_error,
            "status": self.status, "look": self.look_name, "view": self.view.view, "compare": self.view.compare,
            "pinned": self.pinned_name, "shown_controls": list(self.scratch.get("shown_controls", [])),
            "confirm": self.confirm.message if self.confirm else None,
            "params": {k: _jsonable(v) for k, v in self.params.values.items()},
            "stats": {
                "frame_ms": s.frame_ms, "render_ms": s.render_ms, "render_clock": s.render_clock,
                "render_size": list(s.render_size), "label": s.label, "samples": list(s.samples),
                "fibers_41": s.fibers_41, "fibers_exact": s.fibers_exact, "guides": s.guides,
                "segments": s.segments, "scene_gpu_bytes": s.scene_gpu_bytes, "explicit_bytes": s.explicit_bytes,
                "tests_per_pixel": s.tests_per_pixel, "edit_latency_ms": s.edit_latency_ms,
                "gl_renderer": s.gl_renderer, "gl_error": s.gl_error, "refining": s.refining,
                "drawing": s.drawing,
                "frame_gpu_bytes": s.frame_gpu_bytes, "viewer_gpu_bytes": s.viewer_gpu_bytes,
                "estimate": s.estimate, "estimate_slow": s.estimate_slow, "final_held": self.final_held,
            },
        }


def _clamped(candidate: dict[str, Any], accepted: dict[str, Any]) -> tuple[dict[str, Any], str]:
    """Changing the ring count pulls the fiber radius down to 0.5 / rings; the note says why."""
    if "fibers.rings" not in accepted or "fibers.fiber_radius" in accepted:
        return candidate, ""
    rings = candidate["fibers.rings"]
    limit = max_fiber_radius(rings)
    fr = candidate["fibers.fiber_radius"]
    if fr <= limit * (1 + 1e-12):
        return candidate, ""
    note = (f"clamped from {fr:g} to {limit:g} = 0.5 / {rings} rings: each ring is 1/{rings} of the "
            "container radius wide, and a fiber must fit inside its ring")
    return {**candidate, "fibers.fiber_radius": limit}, note


def _valid_alone(key: str, value: Any) -> bool:
    try:
        BY_KEY[key].check(value)
    except ParamError:
        return False
    return True


def _jsonable(v: Any) -> Any:
    return list(v) if isinstance(v, tuple) else v


def _with_groom_defaults(old: Params, new: Params, accepted: dict[str, Any]) -> Params:
    """fibers.groom_auto as the command line applies it (app/scene/grooms/defaults.py): when it is turned on,
    or the groom changes under it, the fiber sliders take the groom's values, except those this edit sets."""
    if not (new["fibers.groom_auto"] and new["scene.generator"] == "groom"):
        return new
    same = ("scene.generator", "scene.groom_file", "scene.groom_radius_scale", "scene.groom_children",
            "fibers.groom_auto")
    if all(old[k] == new[k] for k in same):
        return new
    from ..scene.grooms import GroomError
    from ..scene.grooms.defaults import groom_defaults

    try:
        return groom_defaults(new, set(accepted) - {"fibers.groom_auto"})[0]
    except (GroomError, OSError, ParamError):    # the scene's loader reports a bad file; keep the sliders
        return new


def is_groom_path(target: str) -> bool:
    return Path(target).suffix.lower() in GROOM_SUFFIXES


def spec_keys() -> list[str]:
    return [p.key for p in SPEC]
