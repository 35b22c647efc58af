"""The viewer's panels: ``gui(state)`` reads and edits ``AppState`` and nothing else.

Every parameter widget is built from ``app.params.SPEC`` (kind, bounds, choices, unit, help), so a new
parameter shows up without touching this file; a new group gets its own section. Things that need the
GPU or the window (screenshots, OSL export, quitting) are queued with ``state.request``.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from imgui_bundle import imgui

from ..params import BY_KEY, SPEC, Param, max_fiber_radius
from ..presets import bundled_names, presets_dir
from ..render.budget import _duration
from ..scene.grooms import GROOM_SUFFIXES
from ..units import human_bytes
from .display import HEAT_STOPS
from . import vocabulary as words
from .state import (EXPLICIT_FORMULA, FRAME_PATHS, INTERACTIVE_MODES, INTERACTIVE_SCALES, TURNTABLE_TURNS,
                    VIEWS, AppState, is_groom_path)

# Panel sections, labels and which controls apply: app/viewer/vocabulary.py (no imgui there).
SECTIONS = words.SECTIONS

SHORTCUTS: tuple[tuple[str, str], ...] = (
    ("LMB drag", "orbit"),
    ("MMB drag / Shift+LMB drag", "pan"),
    ("Wheel / Ctrl+LMB drag / + -", "zoom (trackpad: Ctrl+drag, + -)"),
    ("Arrows / Shift+Arrows", "orbit 15 degrees / pan"),
    ("F", "frame the whole scene"),
    ("Home / R", "reset the camera to the preset's"),
    ("T", "turntable on/off"),
    ("P", "pin the current look as A (compare A | B)"),
    ("1 .. 7", "views: " + ", ".join(VIEWS)),
    ("Tab", "show/hide the panel"),
    ("Ctrl+O / Ctrl+S / Ctrl+Shift+S", "open / save / save as"),
    ("Ctrl+Z / Ctrl+Shift+Z, Ctrl+Y", "undo / redo (parameters, not camera moves)"),
    ("F12", "screenshot"),
    ("F1", "this help"),
    ("Ctrl+Q", "quit"),
    ("Ctrl+click a slider", "type a value"),
    ("Right-click a field", "reset to default"),
)

RED = imgui.ImVec4(1.0, 0.42, 0.38, 1.0)
AMBER = imgui.ImVec4(1.0, 0.78, 0.35, 1.0)
DIM = imgui.ImVec4(0.6, 0.6, 0.6, 1.0)


@dataclass
class Layout:
    """Where the render goes, in points (imgui's logical pixels), top-left origin."""

    x: float
    y: float
    w: float
    h: float


def gui(state: AppState) -> Layout:
    """Draw every panel for this frame; returns the viewport area left for the render."""
    scratch = state_scratch(state)
    io = imgui.get_io()
    _shortcuts(state, scratch)
    menu_h = _menu_bar(state, scratch)
    dw, dh = io.display_size.x, io.display_size.y
    panel_w = min(state.view.panel_width * _ui_scale(), dw * 0.6) if state.view.show_panel else 0.0
    if state.view.show_panel:
        _panel(state, scratch, dw - panel_w, menu_h, panel_w, dh - menu_h)
    layout = Layout(0.0, menu_h, max(dw - panel_w, 1.0), max(dh - menu_h, 1.0))
    if state.view.show_stats:
        _stats_overlay(state, layout)
    _legends(state, layout)
    if state.view.show_help:
        _help_window(state)
    _dialogs(state, scratch)
    if not imgui.is_any_item_active():
        state.end_gesture()
        state.dragging = False
    else:
        state.dragging = True
    return layout


def state_scratch(state: AppState) -> dict[str, Any]:
    """Text typed into dialogs and fields before it is applied (plain values kept on the state)."""
    state.scratch.setdefault("open_popup", None)
    return state.scratch


def _ui_scale() -> float:
    return imgui.get_style().font_scale_dpi or 1.0


# --- keyboard -----------------------------------------------------------------------------------------

def _shortcuts(state: AppState, scratch: dict[str, Any]) -> None:
    io = imgui.get_io()
    if io.want_text_input or imgui.is_popup_open("", imgui.PopupFlags_.any_popup_id):
        return
    ctrl, shift = io.key_ctrl, io.key_shift
    K = imgui.Key
    pressed = lambda k: imgui.is_key_pressed(k, False)  # noqa: E731
    if pressed(K.f1):
        state.view.show_help = not state.view.show_help
    if pressed(K.tab):
        state.view.show_panel = not state.view.show_panel
    if pressed(K.f12):
        scratch["open_popup"] = "Screenshot"
    if ctrl:
        if pressed(K.o):
            scratch["open_popup"] = "Open preset"
        if pressed(K.s):
            if shift or state.preset_path is None:
                scratch["open_popup"] = "Save preset as"
            else:
                state.save()
        if pressed(K.z):
            state.redo() if shift else state.undo()
        if pressed(K.y):
            state.redo()
        if pressed(K.q):
            state.request("quit")
        return
    if pressed(K.p):
        state.pin()
    digits = (K._1, K._2, K._3, K._4, K._5, K._6, K._7)
    for i, key in enumerate(digits[:len(VIEWS)]):
        if pressed(key):
            state.view.view = VIEWS[i]
            state.touch()


# --- menu bar -----------------------------------------------------------------------------------------

LOOK_TOOLTIP = ("A preset's look on the groom: its fibers, shape, look and light.\n"
                "The groom keeps its strands (scene), its camera and its quality settings.\n"
                "File > Open... with a preset does the same while a groom is on screen.")


def _menu_bar(state: AppState, scratch: dict[str, Any]) -> float:
    if not imgui.begin_main_menu_bar():
        return 0.0
    if imgui.begin_menu("File"):
        if imgui.menu_item_simple("Open...", "Ctrl+O"):
            scratch["open_popup"] = "Open preset"
        names = bundled_names()
        if state.on_groom:   # on a groom a preset is a look: the groom's strands and camera stay
            if imgui.begin_menu("Apply bundled look", bool(names)):
                imgui.text_disabled("the groom keeps its strands, camera and quality")
                imgui.separator()
                for name in names:
                    if imgui.menu_item_simple(name, "", name == state.look_name):
                        state.open(name)
                    imgui.set_item_tooltip(LOOK_TOOLTIP)
                imgui.end_menu()
        if imgui.begin_menu("Open bundled preset", bool(names)):
            for name in names:
                if imgui.menu_item_simple(name):
                    state.open(name, whole=True)
            imgui.end_menu()
        if not names:
            imgui.set_item_tooltip("no bundled presets installed yet (presets/*.toml)")
        elif state.on_groom:
            imgui.set_item_tooltip("the whole preset, its own scene and camera: leaves the groom")
        imgui.separator()
        if imgui.menu_item_simple("Save", "Ctrl+S"):
            if state.preset_path is None:
                scratch["open_popup"] = "Save preset as"
            else:
                state.save()
        if imgui.menu_item_simple("Save As...", "Ctrl+Shift+S"):
            scratch["open_popup"] = "Save preset as"
        if imgui.menu_item_simple("Revert", "", False, state.dirty or state.preset_path is not None):
            state.revert()
        imgui.separator()
        if imgui.menu_item_simple("Screenshot...", "F12"):
            scratch["open_popup"] = "Screenshot"
        if imgui.menu_item_simple("Render turntable..."):
            scratch["open_popup"] = "Render turntable"
        if imgui.menu_item_simple("Export OSL...", "", False, state.osl_available):
            scratch["open_popup"] = "Export OSL"
        if not state.osl_available:
            imgui.set_item_tooltip("app.export.osl is not installed in this build")
        if imgui.menu_item_simple("Export Blender scene...", "", False, state.osl_available):
            scratch["open_popup"] = "Export Blender scene"
        imgui.separator()
        if imgui.menu_item_simple("Quit", "Ctrl+Q"):
            state.request("quit")
        imgui.end_menu()
    if imgui.begin_menu("Edit"):
        if imgui.menu_item_simple("Undo", "Ctrl+Z"):
            state.undo()
        if imgui.menu_item_simple("Redo", "Ctrl+Shift+Z"):
            state.redo()
        imgui.separator()
        if imgui.menu_item_simple("Reset every parameter to its default"):
            state.begin_gesture()
            state.edit_many({p.key: p.default for p in SPEC if p.group != "camera"})
        imgui.end_menu()
    if imgui.begin_menu("View"):
        for i, name in enumerate(VIEWS):
            if imgui.menu_item_simple(name, str(i + 1), state.view.view == name):
                state.view.view = name
                state.touch()
        imgui.separator()
        _, state.view.show_panel = imgui.menu_item("Panel", "Tab", state.view.show_panel)
        _, state.view.show_stats = imgui.menu_item("Stats overlay", "", state.view.show_stats)
        _, state.view.show_stats_details = imgui.menu_item("Stats details (developer)", "",
                                                           state.view.show_stats_details)
        imgui.separator()
        if imgui.menu_item_simple("Frame all", "F"):
            state.frame_all()
        if imgui.menu_item_simple("Reset camera", "Home"):
            state.reset_camera()
        _, state.view.turntable = imgui.menu_item("Turntable", "T", state.view.turntable)
        lights = state.view.turntable_turns == "lights"
        if imgui.menu_item_simple("Turntable turns the lights", "", lights):
            state.view.turntable_turns = "camera" if lights else "lights"
        imgui.end_menu()
    if imgui.begin_menu("Compare"):
        if imgui.menu_item_simple("Pin current look as A", "P"):
            state.pin()
        if imgui.menu_item_simple("Split A | B", "", state.view.compare == "split", state.pinned is not None):
            state.view.compare = "split"
        if imgui.menu_item_simple("Flip to A", "", state.view.compare == "A only", state.pinned is not None):
            state.view.compare = "A only" if state.view.compare != "A only" else "split"
        if imgui.menu_item_simple("Stop comparing", "", False, state.pinned is not None):
            state.unpin()
        imgui.end_menu()
    if imgui.begin_menu("Help"):
        _, state.view.show_help = imgui.menu_item("Shortcuts", "F1", state.view.show_help)
        imgui.end_menu()
    # what is on screen, right-aligned in the menu bar
    label = state.stats.label
    if label:
        w = imgui.calc_text_size(label).x
        imgui.same_line(imgui.get_window_width() - w - 16)
        imgui.text_colored(AMBER if label.startswith("interactive") else DIM, label)
    h = imgui.get_window_height()
    imgui.end_main_menu_bar()
    return h


# --- the parameter panel ---------------------------------------------------------------------------------

def _panel(state: AppState, scratch: dict[str, Any], x: float, y: float, w: float, h: float) -> None:
    imgui.set_next_window_pos(imgui.ImVec2(x, y), imgui.Cond_.always)
    imgui.set_next_window_size(imgui.ImVec2(w, h), imgui.Cond_.always)
    flags = (imgui.WindowFlags_.no_move | imgui.WindowFlags_.no_resize | imgui.WindowFlags_.no_collapse
             | imgui.WindowFlags_.no_saved_settings)
    imgui.begin("Parameters", None, flags)
    imgui.text(state.display_name + ("*" if state.dirty else ""))
    if state.preset_description:
        imgui.text_disabled(state.preset_description)
        imgui.set_item_tooltip(state.preset_description)
    if state.status:
        imgui.push_text_wrap_pos(0.0)
        imgui.text_colored(RED if state.status.startswith("error") else DIM, state.status)
        imgui.pop_text_wrap_pos()
    if state.shader_error:
        imgui.separator()
        imgui.push_text_wrap_pos(0.0)
        imgui.text_colored(RED, "Shaders do not compile; the last good program (if any) stays on screen. "
                                "Fix the file and save: it reloads by itself.")
        imgui.text_colored(RED, state.shader_error)
        imgui.pop_text_wrap_pos()
    if state.scene_error:
        imgui.separator()
        imgui.push_text_wrap_pos(0.0)
        imgui.text_colored(RED, "Scene not rebuilt: " + state.scene_error)
        imgui.pop_text_wrap_pos()
    _estimate_note(state)   # above the sections: Render is closed by default, and any slider can make a look slow
    imgui.separator()
    imgui.push_item_width(-imgui.get_content_region_avail().x * 0.45)
    shown: list[str] = []
    for title, keys in words.sections():
        flags = imgui.TreeNodeFlags_.default_open if title in words.OPEN_SECTIONS else 0
        if not imgui.collapsing_header(title, flags):
            continue
        if title == "Render":
            imgui.separator_text("image")
        hidden: dict[str, list[str]] = {}
        for key in keys:
            ok, why = words.applies(state.params, key)
            if not ok and key not in state.errors and key not in state.pending:
                hidden.setdefault(why, []).append(words.label(key))
                continue
            if key == "camera.azimuth":
                imgui.separator_text("camera")
            param_widget(state, scratch, BY_KEY[key])
            shown.append(key)
        if hidden:   # what is not shown, and why: nothing disappears without a word
            imgui.push_text_wrap_pos(0.0)
            for why, labels in hidden.items():
                imgui.text_disabled(f"hidden ({why}): {', '.join(labels)}")
            imgui.pop_text_wrap_pos()
    state.scratch["shown_controls"] = shown
    if imgui.collapsing_header("Compare (A/B)", imgui.TreeNodeFlags_.default_open):
        _compare_panel(state)
    if imgui.collapsing_header("Debug"):
        _debug_panel(state)
    imgui.pop_item_width()
    imgui.end()


def _estimate_note(state: AppState) -> None:
    """A final frame that takes seconds or more says so before it starts; a slow one waits for the button."""
    text = state.stats.estimate
    if not text:
        return
    imgui.separator()
    imgui.push_text_wrap_pos(0.0)
    imgui.text_colored(AMBER if state.stats.estimate_slow else DIM, text)
    imgui.pop_text_wrap_pos()
    if state.final_held:
        if imgui.button("Render anyway"):
            state.render_anyway()
        imgui.set_item_tooltip("start the final frame of this look; a smaller window, quality.supersample or "
                               "the fiber density make it quicker")


def _label(p: Param) -> str:
    return f"{words.label(p.key)}##{p.key}"


def tooltip_text(p: Param, extra: str = "") -> str:
    """What hovering a control says: plain help first, then the thesis's name and the preset key."""
    text = [p.help]
    if p.key in words.THESIS:
        text.append("thesis: " + words.THESIS[p.key])
    text += [f"key: {p.key} (presets, --set)", "allowed: " + p.allowed(), f"default: {_fmt_value(p.default)}"]
    if extra:
        text.append(extra)
    text.append("right-click: reset to default")
    return "\n".join(text)


def _tooltip(state: AppState, p: Param, extra: str = "") -> None:
    if imgui.is_item_hovered(imgui.HoveredFlags_.for_tooltip):
        imgui.set_tooltip(tooltip_text(p, extra))


def _relevant(state: AppState, key: str) -> bool:
    return words.applies(state.params, key)[0]


def _fmt_value(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:g}"
    if isinstance(v, tuple):
        return "(" + ", ".join(f"{x:g}" for x in v) + ")"
    return repr(v) if isinstance(v, str) else str(v)


def _float_format(lo: float, hi: float) -> str:
    return "%.2f" if hi - lo >= 10 else "%.3f"


def widget_kind(p: Param) -> str:
    """Which widget a SPEC entry gets, from its kind and bounds alone (so new parameters need no code)."""
    if p.kind is bool:
        return "checkbox"
    if p.choices:
        return "combo"
    if p.kind is str:
        return "text"
    if p.kind is tuple:
        return "color" if ("color" in p.name or "background" in p.name) else "drag3"
    lo = p.lo if p.lo is not None else -math.inf
    hi = p.hi if p.hi is not None else math.inf
    if p.kind is int:
        if hi - lo <= 256:
            return "slider_int"
        return "input_int" if "seed" in p.name else "drag_int"
    if p.key == "fibers.fiber_radius":
        return "fiber_radius"
    return "slider_float" if hi - lo <= 720 else "drag_float"


def param_widget(state: AppState, scratch: dict[str, Any], p: Param) -> None:
    """One field for one SPEC entry: the widget follows the kind and bounds."""
    key = p.key
    kind = widget_kind(p)
    shown = state.value(key)
    if not _type_ok(p, shown):
        shown = state.params[key]
    dim = not _relevant(state, key)
    if dim:
        imgui.push_style_var(imgui.StyleVar_.alpha, 0.5)
    label = _label(p)
    changed, new = False, shown
    extra = ""
    # no_round_to_format: a value typed with ctrl+click keeps every digit, not the display's
    clamp = imgui.SliderFlags_.always_clamp | imgui.SliderFlags_.no_round_to_format
    if kind == "checkbox":
        changed, new = imgui.checkbox(label, bool(shown))
    elif kind == "combo":
        idx = p.choices.index(shown) if shown in p.choices else 0
        changed, i = imgui.combo(label, idx, [words.choice_label(key, c) for c in p.choices])
        new = p.choices[i]
    elif kind == "text":
        buf_key = f"text:{key}"
        text = scratch.get(buf_key, shown)
        entered, text = imgui.input_text(label, text, imgui.InputTextFlags_.enter_returns_true)
        scratch[buf_key] = text
        if entered or (imgui.is_item_deactivated() and text != shown):
            changed, new = True, text
            scratch.pop(buf_key, None)
        extra = "press Enter to apply"
    elif kind in ("color", "drag3"):
        values = [float(x) for x in shown]
        if kind == "color":
            # the numbers stay linear (what presets and --set hold); imgui's own swatch would show them as
            # display values, so it is replaced by color_swatches below
            changed, values = imgui.color_edit3(label, values, imgui.ColorEditFlags_.float
                                                | imgui.ColorEditFlags_.no_small_preview)
        else:
            speed = max(0.001, 0.005 * max(abs(x) for x in values)) if any(values) else 0.01
            changed, values = imgui.drag_float3(label, values, speed, p.lo or 0.0, p.hi or 0.0, "%.4g", clamp)
        new = tuple(float(x) for x in values)
    elif p.kind is int:
        lo, hi = int(p.lo if p.lo is not None else -2**31), int(p.hi if p.hi is not None else 2**31 - 1)
        if kind == "slider_int":
            changed, new = imgui.slider_int(label, int(shown), lo, hi, "%d", clamp)
        elif kind == "input_int":
            changed, new = imgui.input_int(label, int(shown), 1, 100)
            new = min(max(new, lo), hi)
        else:
            speed = max(1.0, abs(int(shown)) * 0.01)
            changed, new = imgui.drag_int(label, int(shown), speed, lo, hi, "%d", clamp)
    else:  # float
        lo = float(p.lo) if p.lo is not None else -1e30
        hi = float(p.hi) if p.hi is not None else 1e30
        if kind == "fiber_radius":
            hi = min(hi, max_fiber_radius(state.params["fibers.rings"]))
            extra = (f"at most 0.5 / rings = {hi:g} with {state.params['fibers.rings']} rings; changing "
                     "the ring count pulls the radius down to fit")
            changed, new = imgui.slider_float(label, float(shown), lo, hi, "%.4f", clamp)
        elif kind == "slider_float":
            fmt = _float_format(lo, hi)
            if p.unit:
                fmt += f" {p.unit.replace('%', '%%')}" if p.unit not in ("units",) else ""
            changed, new = imgui.slider_float(label, float(shown), lo, hi, fmt, clamp)
        else:
            v = float(shown)
            speed = max(abs(v) * 0.005, 1e-4 * (1.0 if hi > 1 else hi))
            changed, new = imgui.drag_float(label, v, speed, lo, hi, "%.5g", clamp)
            if v == 0.0 and key.startswith("camera."):
                extra = "0 = automatic"
    if imgui.is_item_activated():
        state.begin_gesture()
    _tooltip(state, p, extra)
    if imgui.begin_popup_context_item(f"ctx##{key}"):
        if imgui.menu_item_simple("Reset to default"):
            state.begin_gesture()
            state.reset_key(key)
        if imgui.menu_item_simple("Copy key"):
            imgui.set_clipboard_text(key)
        imgui.end_popup()
    if dim:
        imgui.pop_style_var()
    if changed:
        state.edit(key, _tidy(new))
    if key in state.errors:
        imgui.push_text_wrap_pos(0.0)
        imgui.text_colored(RED, state.errors[key])
        imgui.pop_text_wrap_pos()
    if key in state.notes:
        imgui.push_text_wrap_pos(0.0)
        imgui.text_colored(AMBER, state.notes[key])
        imgui.pop_text_wrap_pos()
    if kind == "color" or key in LIT_SWATCH_KEYS:
        picked = color_swatches(state, scratch, p)
        if picked is not None:
            state.edit(key, _tidy(picked))
    if key == "scene.segments" and state.params["scene.generator"] == "groom" and state.stats.guides:
        chosen = state.stats.segments // max(state.stats.guides, 1)
        imgui.text_disabled(f"  {'auto: ' if shown == 1 else ''}{chosen} per guide for this groom")


# Controls whose colour ends up on the fibers: they get an "as lit" swatch besides the colour's own.
LIT_SWATCH_KEYS = ("look.color", "look.tip_color", "look.melanin", "look.tip_melanin")
SWATCH_SIZE = 22.0


def swatch_colors(params, key: str) -> tuple[tuple[int, int, int] | None, tuple[int, int, int] | None]:
    """(colour, as lit) in 8-bit display levels for a control; either may be None.

    colour: the linear value through the renderer's display power (look.display_color): the colour itself,
    as Blender's picker shows a scene-linear colour. as lit: the median colour a lit clump of it shows in
    the picture (look.lit_swatch: tone map, sky fill, white highlight, self-shadow and occlusion of the
    current look and lights, seen from the camera's direction). Melanin controls show their colour."""
    from ..render import look

    p = BY_KEY[key]
    if key in ("look.melanin", "look.tip_melanin"):
        linear = look.base_color(params) if key == "look.melanin" else look.tip_color(params)
    elif p.kind is tuple:
        linear = params[key]
    else:
        return None, None
    lit = look.lit_swatch(params, linear) if key in LIT_SWATCH_KEYS else None
    return look.display_color(linear), lit


def _lit_cache(scratch: dict[str, Any], params, key: str):
    # lit_swatch takes ~10 ms of numpy: once per distinct look, not per UI frame
    stamp = (key, tuple(sorted((k, v) for k, v in params.values.items() if not k.startswith("quality."))))
    cache = scratch.setdefault("swatch_cache", {})
    if stamp not in cache:
        if len(cache) > 64:
            cache.clear()
        cache[stamp] = swatch_colors(params, key)
    return cache[stamp]


def color_swatches(state: AppState, scratch: dict[str, Any], p: Param):
    """The colour's swatch (click: a picker in display space, what you see is what you pick) and, for the
    fibers' colours, the 'as lit' one. Returns a new linear value when the picker changed it, else None."""
    from ..render import look

    try:
        shown, lit = _lit_cache(scratch, state.params, p.key)
    except Exception as exc:  # a swatch must never take the panel down; say why instead
        imgui.text_disabled(f"  (no swatch: {exc})")
        return None
    size = imgui.ImVec2(SWATCH_SIZE, SWATCH_SIZE)
    picked = None
    imgui.indent(8.0)
    if shown is not None:
        col = imgui.ImVec4(*(c / 255.0 for c in shown), 1.0)
        if imgui.color_button(f"colour##sw-{p.key}", col, imgui.ColorEditFlags_.no_tooltip, size) \
                and p.kind is tuple:
            state.begin_gesture()       # one undo step for the whole pick
            imgui.open_popup(f"picker##{p.key}")
        imgui.set_item_tooltip(f"the colour itself, sRGB {shown} (the linear value through the display's "
                               f"power 1/{look.DISPLAY_GAMMA:g}, as the picture is encoded)"
                               + ("; click to pick it on screen" if p.kind is tuple else ""))
        imgui.same_line()
        imgui.text_disabled("colour")
    if lit is not None:
        imgui.same_line()
        imgui.color_button(f"lit##sw-{p.key}", imgui.ImVec4(*(c / 255.0 for c in lit), 1.0),
                           imgui.ColorEditFlags_.no_tooltip, size)
        imgui.set_item_tooltip(f"as lit: sRGB {lit}, the median colour a clump of it shows under the "
                               "current lights, tone map and self-shadow, seen from the camera")
        imgui.same_line()
        imgui.text_disabled("as lit")
    if imgui.begin_popup(f"picker##{p.key}"):
        disp = [(c / 255.0) for c in shown]
        changed, disp = imgui.color_picker3(f"##pick-{p.key}", disp, imgui.ColorEditFlags_.no_side_preview)
        if changed:
            linear = tuple(min(max(float(c), 0.0), 1.0) ** look.DISPLAY_GAMMA for c in disp)
            picked = linear if linear != tuple(state.params[p.key]) else None
        imgui.end_popup()
    imgui.unindent(8.0)
    return picked


def _tidy(v: Any) -> Any:
    """imgui edits float32: keep 6 significant digits so a preset says 0.3, not 0.30000001192092896."""
    if isinstance(v, float):
        return float(f"{v:.6g}")
    if isinstance(v, tuple):
        return tuple(_tidy(x) for x in v)
    return v


def _type_ok(p: Param, v: Any) -> bool:
    if p.kind is bool:
        return isinstance(v, bool)
    if p.kind is str:
        return isinstance(v, str)
    if p.kind is tuple:
        return isinstance(v, (tuple, list)) and len(v) == 3 and all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v)
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and abs(v) < 2**31


def _compare_panel(state: AppState) -> None:
    if imgui.button("Pin current look as A"):
        state.pin()
    imgui.set_item_tooltip("keep this look as A; every change after it shows as B (P)")
    if state.pinned is None:
        imgui.text_disabled("nothing pinned: pin a look, then change sliders to compare")
        return
    imgui.same_line()
    if imgui.button("Stop"):
        state.unpin()
        return
    imgui.text(f"A = {state.pinned_name}, B = the live look")
    from .compare import MODES
    changed, i = imgui.combo("show##compare", MODES.index(state.view.compare), list(MODES))
    if changed:
        state.view.compare = MODES[i]
    if state.view.compare == "split":
        _, state.view.compare_split = imgui.slider_float("split##compare", state.view.compare_split, 0.0, 1.0,
                                                         "%.2f")
    diff = [words.label(k) for k in state.params if not k.startswith("camera.")
            and state.params[k] != state.pinned[k]]
    imgui.push_text_wrap_pos(0.0)
    imgui.text_disabled("B differs in: " + (", ".join(diff) if diff else "nothing yet"))
    imgui.pop_text_wrap_pos()


def _debug_panel(state: AppState) -> None:
    v = state.view
    changed, i = imgui.combo("view##debug", VIEWS.index(v.view), list(VIEWS))
    if changed:
        v.view = VIEWS[i]
        state.touch()
    imgui.set_item_tooltip("keys 1-7; heat map = fiber tests per pixel (a cost render); proxies = the "
                           "container boxes' cylinders as wireframes over the dimmed render")
    _, i = imgui.combo("interactive scale", INTERACTIVE_SCALES.index(v.interactive_scale),
                       list(INTERACTIVE_SCALES))
    v.interactive_scale = INTERACTIVE_SCALES[i]
    imgui.set_item_tooltip("resolution while a slider is dragged or the camera moves (times "
                           "quality.render_scale); auto aims at the budget below")
    if v.interactive_scale == "auto":
        _, v.auto_budget_ms = imgui.slider_float("budget", v.auto_budget_ms, 20.0, 500.0, "%.0f ms")
    _, i = imgui.combo("interactive mode", INTERACTIVE_MODES.index(v.interactive_mode),
                       list(INTERACTIVE_MODES))
    v.interactive_mode = INTERACTIVE_MODES[i]
    imgui.set_item_tooltip("fast: the thesis's traversal order, first hit wins; final mode: quality.mode")
    _, v.refine_delay = imgui.slider_float("refine after", v.refine_delay, 0.05, 2.0, "%.2f s")
    imgui.set_item_tooltip("stillness before the full-resolution frame in quality.mode")
    changed, i = imgui.combo("frame path", FRAME_PATHS.index(v.frame_path), list(FRAME_PATHS))
    if changed:
        v.frame_path = FRAME_PATHS[i]
        state.touch()
    imgui.set_item_tooltip("direct: draw from the renderer's texture; readback: through numpy and an "
                           "upload (compare their frame times in the stats)")
    changed, v.heat_max = imgui.drag_float("heat max", v.heat_max, 1.0, 0.0, 1e6, "%.0f tests")
    imgui.set_item_tooltip("top of the heat-map scale; 0 = the 99th percentile of this view")
    _, v.turntable = imgui.checkbox("turntable", v.turntable)
    imgui.same_line()
    imgui.set_next_item_width(120)
    _, v.turntable_speed = imgui.slider_float("deg/s", v.turntable_speed, -180.0, 180.0, "%.0f")
    _, i = imgui.combo("turntable turns", TURNTABLE_TURNS.index(v.turntable_turns), list(TURNTABLE_TURNS))
    v.turntable_turns = TURNTABLE_TURNS[i]
    imgui.set_item_tooltip("lights: the light rig (rotate all lights) turns under a still camera")


# --- overlays ----------------------------------------------------------------------------------------------

def _overlay_begin(name: str, x: float, y: float, pivot=(0.0, 0.0)) -> bool:
    imgui.set_next_window_pos(imgui.ImVec2(x, y), imgui.Cond_.always, imgui.ImVec2(*pivot))
    imgui.set_next_window_bg_alpha(0.55)
    flags = (imgui.WindowFlags_.no_decoration | imgui.WindowFlags_.always_auto_resize
             | imgui.WindowFlags_.no_saved_settings | imgui.WindowFlags_.no_focus_on_appearing
             | imgui.WindowFlags_.no_nav | imgui.WindowFlags_.no_inputs | imgui.WindowFlags_.no_move)
    return imgui.begin(name, None, flags)[0]


def stats_lines(state: AppState) -> list[str]:
    """The overlay in plain words: what is on screen, how many strands, how fast, how little memory."""
    s = state.stats
    w, h = s.render_size
    samples = f", {s.samples[0]}/{s.samples[1]} samples" if s.samples[1] > 1 else ""
    lines = [f"{s.label or '-'}: {w}x{h}{samples}, {s.render_ms:.0f} ms",
             f"{s.fibers_exact:,} strands drawn from {s.guides:,} guide hairs",
             f"memory: {human_bytes(s.scene_gpu_bytes)} (storing every strand: {human_bytes(s.explicit_bytes)})"
             + frame_bytes_text(s)]
    if state.final_held:
        lines.append(f"final frame waits (about {_duration(s.estimate_seconds)}): Render anyway, in the panel")
    if state.pinned is not None and state.view.compare != "off":
        split = state.view.compare == "split"
        lines.append(f"A: {state.pinned_name} | B: live" if split else f"showing A: {state.pinned_name}")
    return lines


def _stats_overlay(state: AppState, layout: Layout) -> None:
    """Bottom-right corner of the render: hair is framed in the middle, so a corner keeps it clear."""
    s = state.stats
    if _overlay_begin("##stats", layout.x + layout.w - 10, layout.y + layout.h - 10, (1.0, 1.0)):
        for i, line in enumerate(stats_lines(state)):
            if i == 0:
                imgui.text_colored(AMBER if s.label.startswith("interactive") else DIM, line)
            else:
                imgui.text(line)
        if state.view.show_stats_details:
            imgui.separator()
            imgui.text(f"frame {s.frame_ms:.1f} ms (median), fibers {s.render_ms:.1f} ms ({s.render_clock})")
            if s.edit_latency_ms is not None:
                imgui.text(f"change -> frame {s.edit_latency_ms:.0f} ms")
            imgui.text(f"thesis expression 4.1: {s.fibers_41:,.0f} fibers; {s.segments:,} container segments")
            ratio = s.explicit_bytes / s.scene_gpu_bytes if s.scene_gpu_bytes else 0.0
            imgui.text(f"explicit / virtual memory: {ratio:,.0f}x")
            if s.tests_per_pixel is not None:
                imgui.text(f"fiber tests / covered pixel {s.tests_per_pixel:.1f} (p99 {s.tests_p99:.0f})")
            imgui.text_disabled(s.gl_renderer)
        if s.gl_error != "GL_NO_ERROR":
            imgui.text_colored(RED, f"GL error: {s.gl_error}")
    imgui.end()


def _legends(state: AppState, layout: Layout) -> None:
    """A colour scale under the views that map a number to a colour."""
    s, view = state.stats, state.view.view
    if view == "heat map":
        top = state.view.heat_max or s.tests_p99 or 1.0
        auto = "" if state.view.heat_max else " (top: 99th percentile)"
        _legend(layout, "fiber tests per pixel" + auto, HEAT_STOPS, ("0", f"{top / 2:.0f}", f"{top:.0f}+"))
    elif view == "rings":
        k = state.params["fibers.rings"]
        _legend(layout, "ring index", HEAT_STOPS, ("outer 0", "", f"inner {k - 1}"))
    elif view == "depth":
        near, far = s.depth_range
        _legend(layout, "distance along the ray", ((1.0, 1.0, 1.0), (0.15, 0.15, 0.15)),
                (f"{near:.3g}", "", f"{far:.3g}"))


def _legend(layout: Layout, title: str, stops, labels: tuple[str, str, str]) -> None:
    if _overlay_begin("##legend", layout.x + 10, layout.y + layout.h - 10, (0.0, 1.0)):
        imgui.text(title)
        dl = imgui.get_window_draw_list()
        pos = imgui.get_cursor_screen_pos()
        width, height = 260.0 * _ui_scale(), 14.0 * _ui_scale()
        n = len(stops) - 1
        for i in range(n):
            ca = imgui.get_color_u32(imgui.ImVec4(*stops[i], 1.0))
            cb = imgui.get_color_u32(imgui.ImVec4(*stops[i + 1], 1.0))
            x0, x1 = pos.x + width * i / n, pos.x + width * (i + 1) / n
            dl.add_rect_filled_multi_color(imgui.ImVec2(x0, pos.y), imgui.ImVec2(x1, pos.y + height), ca, cb, cb, ca)
        imgui.dummy(imgui.ImVec2(width, height))
        left, mid, right = labels
        imgui.text(left)
        if mid:
            imgui.same_line(width / 2 - imgui.calc_text_size(mid).x / 2)
            imgui.text(mid)
        imgui.same_line(width - imgui.calc_text_size(right).x)
        imgui.text(right)
    imgui.end()


def _help_window(state: AppState) -> None:
    # sized to the screen and kept inside it; the right column wraps instead of running off the edge
    vp = imgui.get_main_viewport()
    width = min(640 * _ui_scale(), vp.size.x - 40)
    imgui.set_next_window_size(imgui.ImVec2(width, 0), imgui.Cond_.appearing)
    imgui.set_next_window_pos(vp.get_center(), imgui.Cond_.appearing, imgui.ImVec2(0.5, 0.5))
    imgui.set_next_window_size_constraints(imgui.ImVec2(200, 0), imgui.ImVec2(vp.size.x - 20, vp.size.y - 40))
    opened, state.view.show_help = imgui.begin("Shortcuts (F1)", state.view.show_help,
                                               imgui.WindowFlags_.no_saved_settings)
    flags = imgui.TableFlags_.row_bg | imgui.TableFlags_.borders_inner_v | imgui.TableFlags_.sizing_stretch_prop
    if opened and imgui.begin_table("keys", 2, flags):
        imgui.table_setup_column("key", imgui.TableColumnFlags_.width_stretch, 0.45)
        imgui.table_setup_column("what", imgui.TableColumnFlags_.width_stretch, 0.55)
        for key, what in SHORTCUTS:
            imgui.table_next_row()
            imgui.table_next_column()
            imgui.push_text_wrap_pos(0.0)
            imgui.text(key)
            imgui.pop_text_wrap_pos()
            imgui.table_next_column()
            imgui.push_text_wrap_pos(0.0)
            imgui.text(what)
            imgui.pop_text_wrap_pos()
        imgui.end_table()
    if opened:
        imgui.push_text_wrap_pos(0.0)
        imgui.text_disabled("Camera moves are saved with a preset but do not mark it modified. While "
                            "something moves, the view renders at the interactive scale; after the refine "
                            "delay it renders at full resolution in quality.mode, then accumulates "
                            "quality.supersample^2 samples.")
        imgui.separator_text("The stats overlay")
        imgui.text_disabled("strands: whole fibers per ring summed over rings x guide hairs (View > Stats "
                            "details adds the thesis's expression 4.1, the sum of 360/phi_step). Memory: the "
                            "container buffer plus the proxy rectangle; storing every strand: " + EXPLICIT_FORMULA
                            + ". Fiber tests / covered pixel: a cost render (at most 640x360) after each still "
                            "frame. Times: a GPU timer query (32-bit: past 4.29 s the wall clock is shown).")
        imgui.pop_text_wrap_pos()
    imgui.end()


# --- dialogs -----------------------------------------------------------------------------------------------

def _open_requested(scratch: dict[str, Any]) -> None:
    name = scratch.get("open_popup")
    if name:
        imgui.open_popup(name)
        scratch["open_popup"] = None


def _dialogs(state: AppState, scratch: dict[str, Any]) -> None:
    for command, args in list(state.commands):
        if command == "ask_save_as":
            state.commands.remove((command, args))
            scratch["open_popup"] = "Save preset as"
    if state.last_error and not imgui.is_popup_open("Error"):
        scratch["open_popup"] = "Error"
    if state.confirm and not imgui.is_popup_open("Unsaved changes"):
        scratch["open_popup"] = "Unsaved changes"
    _open_requested(scratch)
    center = imgui.get_main_viewport().get_center()
    auto = imgui.WindowFlags_.always_auto_resize | imgui.WindowFlags_.no_saved_settings

    imgui.set_next_window_pos(center, imgui.Cond_.appearing, imgui.ImVec2(0.5, 0.5))
    if imgui.begin_popup_modal("Error", None, auto)[0]:
        imgui.push_text_wrap_pos(640 * _ui_scale())
        imgui.text_colored(RED, state.last_error or "")
        if state.last_error_key:
            imgui.text(f"key: {state.last_error_key}")
        imgui.text_disabled("Nothing was changed: the scene on screen is the one you had.")
        imgui.pop_text_wrap_pos()
        if imgui.button("OK") or imgui.is_key_pressed(imgui.Key.enter) or imgui.is_key_pressed(imgui.Key.escape):
            state.close_error()
            imgui.close_current_popup()
        imgui.end_popup()

    imgui.set_next_window_pos(center, imgui.Cond_.appearing, imgui.ImVec2(0.5, 0.5))
    if imgui.begin_popup_modal("Unsaved changes", None, auto)[0]:
        imgui.text(state.confirm.message if state.confirm else "")
        if imgui.button("Save"):
            if state.preset_path is None:
                state.answer_confirm("cancel")
                scratch["open_popup"] = "Save preset as"
            else:
                state.answer_confirm("save")
            imgui.close_current_popup()
        imgui.same_line()
        if imgui.button("Discard changes"):
            state.answer_confirm("discard")
            imgui.close_current_popup()
        imgui.same_line()
        if imgui.button("Cancel") or imgui.is_key_pressed(imgui.Key.escape):
            state.answer_confirm("cancel")
            imgui.close_current_popup()
        imgui.end_popup()

    _path_dialog(state, scratch, "Open preset", "Open", _default_dir(state), _do_open, list_files=True,
                 note=("a groom is on screen: a preset opened here is a look on it (fibers, shape, look, light); "
                       "the strands and camera stay") if state.on_groom else "")
    _save_as_dialog(state, scratch, center, auto)
    _screenshot_dialog(state, scratch, center, auto)
    _turntable_dialog(state, scratch, center, auto)
    _path_dialog(state, scratch, "Export OSL", "Export", str(Path(_default_dir(state)) /
                 f"{Path(state.display_name).stem or 'vfiber'}.osl"),
                 lambda st, path: st.request("export_osl", path=path))
    _path_dialog(state, scratch, "Export Blender scene", "Export", str(Path(_default_dir(state)) /
                 f"{Path(state.display_name).stem or 'vfiber'}.blend"),
                 lambda st, path: st.request("export_blend", path=path))


def _default_dir(state: AppState) -> str:
    return str(state.preset_path.parent if state.preset_path else Path.cwd())


def _do_open(state: AppState, path: str) -> None:
    """A groom goes under the look on screen; a preset, while a groom is on screen, is a look on it."""
    if is_groom_path(path):
        state.open_groom(path)
    else:
        state.open(path)


def _path_dialog(state: AppState, scratch: dict[str, Any], name: str, verb: str, default: str,
                 action: Callable[[AppState, str], None], list_files: bool = False, note: str = "") -> None:
    center = imgui.get_main_viewport().get_center()
    imgui.set_next_window_pos(center, imgui.Cond_.appearing, imgui.ImVec2(0.5, 0.5))
    imgui.set_next_window_size(imgui.ImVec2(620 * _ui_scale(), 0), imgui.Cond_.appearing)
    if not imgui.begin_popup_modal(name, None, imgui.WindowFlags_.no_saved_settings)[0]:
        scratch.pop(f"path:{name}", None)
        return
    key = f"path:{name}"
    if key not in scratch:
        scratch[key] = default if default.endswith((".toml", ".osl", ".png")) else default.rstrip("/") + "/"
        imgui.set_keyboard_focus_here()
    imgui.set_next_item_width(-1)
    entered, scratch[key] = imgui.input_text("##path", scratch[key], imgui.InputTextFlags_.enter_returns_true)
    if note:
        imgui.push_text_wrap_pos(0.0)
        imgui.text_disabled(note)
        imgui.pop_text_wrap_pos()
    if list_files:
        folder = Path(scratch[key]).expanduser()
        folder = folder if folder.is_dir() else folder.parent
        files = sorted(list(folder.glob("*.toml")) + [f for s in GROOM_SUFFIXES
                                                      for f in folder.glob(f"*{s}")])[:200] if folder.is_dir() else []
        bundled = presets_dir()
        if imgui.begin_child("files", imgui.ImVec2(0, 180 * _ui_scale()), imgui.ChildFlags_.borders):
            for f in files:
                if imgui.selectable(f.name, str(f) == scratch[key])[0]:
                    scratch[key] = str(f)
                    if imgui.is_mouse_double_clicked(imgui.MouseButton_.left):
                        entered = True
            if bundled is not None:
                for f in sorted(bundled.glob("*.toml")):
                    if imgui.selectable(f"[bundled] {f.stem}", False)[0]:
                        scratch[key] = str(f)
            if not files:
                imgui.text_disabled(f"no presets or grooms in {folder}")
        imgui.end_child()
    if imgui.button(verb) or entered:
        path = os.path.expanduser(scratch.pop(key))
        imgui.close_current_popup()
        action(state, path)
    imgui.same_line()
    if imgui.button("Cancel") or imgui.is_key_pressed(imgui.Key.escape):
        scratch.pop(key, None)
        imgui.close_current_popup()
    imgui.end_popup()


def _save_as_dialog(state: AppState, scratch: dict[str, Any], center, flags) -> None:
    imgui.set_next_window_pos(center, imgui.Cond_.appearing, imgui.ImVec2(0.5, 0.5))
    imgui.set_next_window_size(imgui.ImVec2(620 * _ui_scale(), 0), imgui.Cond_.appearing)
    if not imgui.begin_popup_modal("Save preset as", None, imgui.WindowFlags_.no_saved_settings)[0]:
        scratch.pop("save_as", None)
        return
    form = scratch.setdefault("save_as", {
        "path": str(state.preset_path or Path.cwd() / f"{state.display_name}.toml"),
        "name": state.preset_name, "description": state.preset_description})
    _, form["path"] = imgui.input_text("file", form["path"])
    _, form["name"] = imgui.input_text("name", form["name"])
    _, form["description"] = imgui.input_text("description", form["description"])
    imgui.set_item_tooltip("one line: what you should see when it renders")
    exists = Path(form["path"]).expanduser().exists() and Path(form["path"]).expanduser() != state.preset_path
    if exists:
        imgui.text_colored(AMBER, "a file of that name exists and will be replaced")
    if imgui.button("Save"):
        imgui.close_current_popup()
        state.save_as(os.path.expanduser(form["path"]), form["name"], form["description"])
        scratch.pop("save_as", None)
    imgui.same_line()
    if imgui.button("Cancel") or imgui.is_key_pressed(imgui.Key.escape):
        scratch.pop("save_as", None)
        imgui.close_current_popup()
    imgui.end_popup()


def _turntable_dialog(state: AppState, scratch: dict[str, Any], center, flags) -> None:
    imgui.set_next_window_pos(center, imgui.Cond_.appearing, imgui.ImVec2(0.5, 0.5))
    if not imgui.begin_popup_modal("Render turntable", None, flags)[0]:
        return
    form = scratch.setdefault("turntable", {"path": str(Path.cwd() / f"{Path(state.display_name).stem}-turntable"),
                                            "frames": 36, "size": [1280, 720], "alpha": False})
    imgui.set_next_item_width(460 * _ui_scale())
    _, form["path"] = imgui.input_text("folder", form["path"])
    _, form["frames"] = imgui.slider_int("frames", form["frames"], 4, 360)
    _, form["size"] = imgui.input_int2("size", form["size"])
    form["size"] = [min(max(int(x), 16), 8192) for x in form["size"]]
    _, form["alpha"] = imgui.checkbox("alpha (coverage) in the PNGs", form["alpha"])
    imgui.text_disabled("frame_0000.png ... one full turn of the camera; turntable.mp4 too where ffmpeg is "
                        "installed")
    if imgui.button("Render"):
        state.request("turntable", path=os.path.expanduser(form["path"]), frames=form["frames"],
                      size=tuple(form["size"]), alpha=form["alpha"])
        imgui.close_current_popup()
    imgui.same_line()
    if imgui.button("Cancel") or imgui.is_key_pressed(imgui.Key.escape):
        imgui.close_current_popup()
    imgui.end_popup()


def _screenshot_dialog(state: AppState, scratch: dict[str, Any], center, flags) -> None:
    imgui.set_next_window_pos(center, imgui.Cond_.appearing, imgui.ImVec2(0.5, 0.5))
    if not imgui.begin_popup_modal("Screenshot", None, flags)[0]:
        return
    w, h = state.stats.render_size if state.stats.render_size != (0, 0) else (1280, 720)
    form = scratch.setdefault("shot", {"path": str(Path.cwd() / f"{Path(state.display_name).stem}.png"),
                                       "size": [1920, 1080], "view": False})
    imgui.set_next_item_width(460 * _ui_scale())
    _, form["path"] = imgui.input_text("file", form["path"])
    _, form["size"] = imgui.input_int2("size", form["size"])
    form["size"] = [min(max(int(x), 1), 16384) for x in form["size"]]
    for label, size in (("720p", (1280, 720)), ("1080p", (1920, 1080)), ("4K", (3840, 2160)),
                        ("square", (1024, 1024)), ("viewport", (w, h))):
        imgui.same_line() if label != "720p" else None
        if imgui.small_button(label):
            form["size"] = list(size)
    _, form["view"] = imgui.checkbox(f"this debug view ({state.view.view}) instead of shaded", form["view"])
    imgui.text_disabled(f"shaded uses quality.supersample = {state.params['quality.supersample']} "
                        f"({state.params['quality.supersample'] ** 2} samples), quality.mode = "
                        f"{state.params['quality.mode']}")
    if imgui.button("Save PNG"):
        state.request("screenshot", path=os.path.expanduser(form["path"]), size=tuple(form["size"]),
                      view=state.view.view if form["view"] else "shaded")
        imgui.close_current_popup()
    imgui.same_line()
    if imgui.button("Cancel") or imgui.is_key_pressed(imgui.Key.escape):
        imgui.close_current_popup()
    imgui.end_popup()


# --- issue 12: progress of a frame that refines in strips, per-pixel buffer bytes -------------------

def refine_overlay(state: AppState, layout: Layout) -> None:
    """"refining n%" in the viewport's lower right corner while a slow frame is drawn in strips, and
    "loading ..." while a scene is built."""
    s = state.stats
    loading = state.status.startswith("loading ")
    if s.refining is None and not loading:
        return
    if _overlay_begin("##refining", layout.x + layout.w - 10, layout.y + layout.h - 10, (1.0, 1.0)):
        text = state.status if loading else f"refining {min(s.refining, 0.999) * 100:.0f}%"
        imgui.text_colored(AMBER, text)
    imgui.end()


def frame_bytes_text(s) -> str:
    """The per-pixel buffers next to the scene's bytes (the renderer's count where it keeps one)."""
    renderer = f"{human_bytes(s.frame_gpu_bytes)} + " if s.frame_gpu_bytes is not None else ""
    return f"   per-pixel {renderer}{human_bytes(s.viewer_gpu_bytes)} viewer"
