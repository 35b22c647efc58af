"""Camera navigation: mouse and keys in, ``camera.*`` parameters out.

The controller never sees imgui or glfw: the app turns a frame's input into an ``Input`` snapshot, a
script can build one by hand, and a test can check the arithmetic without a window. Every move goes
through ``AppState.set_camera`` (validated, no undo step, no unsaved-changes mark).

Bindings (Blender-like, with trackpad fallbacks):

    LMB drag               orbit                  wheel / ctrl+LMB drag / + -   zoom
    MMB drag, shift+LMB    pan                    F                             frame all
    Home, R                reset to the preset    T                             turntable on/off
    arrow keys             orbit 15 degrees       shift+arrows                  pan a tenth of the view
"""

from __future__ import annotations

import copy
import inspect
import math
from dataclasses import dataclass, field

import numpy as np

from ..params import Params
from ..render.camera import Camera
from ..scene.containers import Scene
from .state import AppState

ORBIT_DEG_PER_PIXEL = 0.35
WHEEL_ZOOM = 0.88          # distance factor per wheel notch toward the target
DRAG_ZOOM_PER_PIXEL = 0.005
KEY_ORBIT_DEG = 15.0
MIN_DISTANCE_FRACTION = 1e-4  # of the scene's bounding radius


@dataclass
class Input:
    """One frame of viewport input, in framebuffer pixels (y grows downward, as on screen)."""

    dx: float = 0.0
    dy: float = 0.0
    left: bool = False
    middle: bool = False
    right: bool = False
    wheel: float = 0.0
    shift: bool = False
    ctrl: bool = False
    alt: bool = False
    keys: set[str] = field(default_factory=set)   # pressed this frame: "F", "HOME", "R", "T", "LEFT", ...
    dt: float = 0.0                                # seconds since the last frame (turntable)


def make_camera(p: Params, scene: Scene, aspect: float) -> Camera:
    """``Camera.from_params`` with the viewport's aspect where the camera module takes one (automatic
    framing then fits the width too), without it where it does not.

    The last few cameras are kept: the viewer asks for them several times a UI frame, and framing a
    158,100-segment groom costs ~12-20 ms each time. More than one, because a UI frame asks at two aspects
    (the viewport's and the render size's, which rounding makes differ): with one kept, every interactive
    frame of harolongo framed twice (~23 ms of its ~100 ms). A copy is handed out, so a caller that moves it
    cannot move the cache."""
    key = (tuple((k, v) for k, v in p.values.items() if k.startswith("camera.")), float(aspect))
    for i, (k, sc, cam) in enumerate(_cameras):
        if k == key and sc is scene:
            _cameras.insert(0, _cameras.pop(i))
            return copy.deepcopy(cam)
    cam = Camera.from_params(p, scene, aspect=aspect) if _TAKES_ASPECT else Camera.from_params(p, scene)
    _cameras.insert(0, (key, scene, copy.deepcopy(cam)))
    del _cameras[KEPT_CAMERAS:]
    return cam


KEPT_CAMERAS = 4
_cameras: list[tuple[tuple, Scene, Camera]] = []       # most recently used first


_TAKES_ASPECT = "aspect" in inspect.signature(Camera.from_params).parameters


def _wrap(deg: float) -> float:
    return (deg + 180.0) % 360.0 - 180.0


class CameraController:
    def __init__(self) -> None:
        self.moving = False      # a drag moved the camera this frame

    def update(self, state: AppState, scene: Scene | None, inp: Input, viewport: tuple[int, int]) -> bool:
        """Apply one frame of input (``viewport``: the render area in pixels). True when the camera moved."""
        viewport_height = max(int(viewport[1]), 1)
        aspect = max(int(viewport[0]), 1) / viewport_height
        self.moving = False
        p = state.params
        changes: dict[str, object] = {}
        az, el = p["camera.azimuth"], p["camera.elevation"]

        if "F" in inp.keys:
            state.frame_all()
            return True
        if "HOME" in inp.keys or "R" in inp.keys:
            state.reset_camera()
            return True
        if "T" in inp.keys:
            state.view.turntable = not state.view.turntable
            state.status = f"turntable {'on' if state.view.turntable else 'off'}"
        if scene is None:
            return False

        pan_px = (0.0, 0.0)
        zoom = 1.0
        # mouse drags: shift+LMB or MMB pan, ctrl+LMB zoom, LMB orbit (alt+LMB orbits too, as in Maya)
        if inp.dx or inp.dy:
            if inp.middle or (inp.left and inp.shift):
                pan_px = (inp.dx, inp.dy)
            elif inp.left and inp.ctrl:
                zoom *= math.exp(inp.dy * DRAG_ZOOM_PER_PIXEL * 2.0)
            elif inp.left or (inp.right and inp.alt):
                az -= inp.dx * ORBIT_DEG_PER_PIXEL
                el += inp.dy * ORBIT_DEG_PER_PIXEL
        if inp.wheel:
            zoom *= WHEEL_ZOOM ** inp.wheel
        for key, step in (("PLUS", 1.0), ("MINUS", -1.0), ("PAGE_UP", 1.0), ("PAGE_DOWN", -1.0)):
            if key in inp.keys:
                zoom *= WHEEL_ZOOM ** step
        arrows = {"LEFT": (-1, 0), "RIGHT": (1, 0), "UP": (0, -1), "DOWN": (0, 1)}
        for key, (kx, ky) in arrows.items():
            if key in inp.keys:
                if inp.shift:
                    pan_px = (pan_px[0] + kx * viewport_height * 0.1, pan_px[1] + ky * viewport_height * 0.1)
                else:
                    az -= kx * KEY_ORBIT_DEG
                    el -= ky * KEY_ORBIT_DEG
        if state.view.turntable and inp.dt > 0:
            step = state.view.turntable_speed * min(inp.dt, 0.25)
            if state.view.turntable_turns == "lights":   # the light rig turns, the camera stays
                state.edit("light.rig_rotation", _wrap(p["light.rig_rotation"] + step), undoable=False)
            else:
                az += step

        if az != p["camera.azimuth"] or el != p["camera.elevation"]:
            changes["azimuth"] = _wrap(az)
            changes["elevation"] = float(np.clip(el, -89.9, 89.9))
        if zoom != 1.0 or pan_px != (0.0, 0.0):
            cam = make_camera(p, scene, aspect)
            dist = float(np.linalg.norm(cam.position - cam.target))
            lo, hi = scene.bounds()
            radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-12)
            if zoom != 1.0:
                changes["distance"] = float(np.clip(dist * zoom, radius * MIN_DISTANCE_FRACTION, 1e9))
            if pan_px != (0.0, 0.0):
                # one pixel at the target's depth is 2 d tan(fov/2) / height world units
                per_px = 2.0 * dist * math.tan(math.radians(cam.fov) / 2) / max(viewport_height, 1)
                right, up, _ = cam.basis()
                move = (-pan_px[0] * right + pan_px[1] * up) * per_px
                target = np.asarray(p["camera.target"], np.float64) + move
                changes["target"] = tuple(float(x) for x in np.clip(target, -1e9, 1e9))
        if not changes:
            return False
        self.moving = bool(inp.dx or inp.dy or inp.wheel or state.view.turntable)
        state.set_camera(**changes)
        return True
