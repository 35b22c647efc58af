"""OpenGL contexts: headless (EGL, then OSMesa) for renders and tests, a glfw window for the viewer.

The renderer only ever sees a ``moderngl.Context``; glfw is imported inside ``create_window`` alone.

Every failure becomes a one-line ``GLContextError`` naming the Debian package to install, because the
people who hit these are setting up a machine, not debugging moderngl.

Current-context rule: Mesa's EGL and OSMesa share one GL dispatch (libglapi), and moderngl does not make
its context current before each call. So the most recently created live ``HeadlessContext`` is the
current one; releasing a context makes the newest remaining one current again, and
``hc.make_current()`` switches explicitly. Prefer that to ``with hc.ctx:``: glcontext's EGL enter is
skipped by EGL when EGL believes the context is already current, which is wrong once OSMesa has taken
the dispatch.
"""

from __future__ import annotations

import ctypes
import os
import re
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple

from ..errors import VfiberError

if TYPE_CHECKING:  # moderngl is imported lazily so that a broken install becomes a GLContextError
    import moderngl

BACKENDS: tuple[str, ...] = ("egl", "osmesa")  # auto order: EGL is faster to start and better tested
ENV_BACKEND = "VFIBER_GL_BACKEND"

_EGL_LIBS = ("libEGL.so.1", "libEGL.so")
_OSMESA_LIBS = ("libOSMesa.so.8", "libOSMesa.so.6", "libOSMesa.so")


def _install(*packages: str) -> str:
    return f"install {' '.join(packages)} (apt-get install {' '.join(packages)})"


class GLContextError(VfiberError, RuntimeError):
    """No usable OpenGL context; the message is one line and names what to install."""

    def __init__(self, message: str, attempts: Sequence[tuple[str, str]] = ()) -> None:
        super().__init__(message)
        self.attempts = list(attempts)


def _open_library(names: Sequence[str]) -> ctypes.CDLL:
    """Load the first shared library that opens; OSError names every candidate. Tests patch this."""
    reasons = []
    for name in names:
        try:
            return ctypes.CDLL(name)
        except OSError as exc:
            reasons.append(str(exc))
    raise OSError("; ".join(reasons))


def _import_moderngl() -> Any:
    try:
        import moderngl
    except ImportError as exc:
        raise GLContextError(f"moderngl cannot be imported ({exc}): pip install moderngl") from None
    return moderngl


def _gl_strings(ctx: moderngl.Context) -> tuple[str, str]:
    return str(ctx.info["GL_RENDERER"]), str(ctx.info["GL_VERSION"])


def _version_text(require: int) -> str:
    return f"{require // 100}.{require // 10 % 10}"


# ---------------------------------------------------------------------------------------------- EGL

class _EglState(NamedTuple):
    display: int | None
    draw: int | None
    read: int | None
    context: int | None


_EGL_DRAW, _EGL_READ = 0x3059, 0x305A
_egl_lib: ctypes.CDLL | None = None
_our_egl_contexts: set[int | None] = set()  # EGL keeps a released context current; never "restore" one


def _egl() -> ctypes.CDLL:
    global _egl_lib
    if _egl_lib is None:
        lib = _open_library(_EGL_LIBS)
        for name in ("eglGetCurrentDisplay", "eglGetCurrentContext"):
            getattr(lib, name).restype = ctypes.c_void_p
        lib.eglGetCurrentSurface.restype = ctypes.c_void_p
        lib.eglGetCurrentSurface.argtypes = [ctypes.c_int]
        lib.eglMakeCurrent.argtypes = [ctypes.c_void_p] * 4
        lib.eglMakeCurrent.restype = ctypes.c_uint
        _egl_lib = lib
    return _egl_lib


def _egl_current() -> _EglState:
    lib = _egl()
    return _EglState(lib.eglGetCurrentDisplay(), lib.eglGetCurrentSurface(_EGL_DRAW),
                     lib.eglGetCurrentSurface(_EGL_READ), lib.eglGetCurrentContext())


def _egl_make_current(state: _EglState) -> None:
    lib = _egl()
    # Unbind first: EGL skips a bind to the context it believes current, but OSMesa may have taken
    # the shared GL dispatch since, so only a real switch puts this context back.
    lib.eglMakeCurrent(state.display, None, None, None)
    if not lib.eglMakeCurrent(state.display, state.draw, state.read, state.context):
        raise GLContextError("eglMakeCurrent failed: is a window's GLX context current on this thread? "
                             "call glfw.make_context_current(None) first")


def _egl_unbind() -> None:
    """Let go of an EGL context current on this thread: glvnd refuses GLX while EGL is current
    (an X BadAccess that aborts the process), so a window cannot be made current otherwise."""
    if _egl_lib is not None:
        state = _egl_current()
        if state.context:
            _egl_lib.eglMakeCurrent(state.display, None, None, None)


_EGL_HINTS: tuple[tuple[str, str], ...] = (
    # (substring of the glcontext/moderngl message, what to tell a person)
    ("libEGL", f"EGL could not load libEGL.so.1: {_install('libegl1', 'libegl-mesa0')}"),
    ("libGL", f"EGL could not load libGL.so.1: {_install('libgl1')}"),
    ("eglInitialize", f"EGL found no DRI driver (swrast): {_install('libgl1-mesa-dri', 'libegl-mesa0')}"),
    ("0 devices", f"EGL found no device (no Mesa EGL vendor): {_install('libegl-mesa0', 'libgl1-mesa-dri')}"),
    ("eglCreateContext", "EGL could not create an OpenGL {version} core context: upgrade Mesa "
                         "(libgl1-mesa-dri >= 20.3 gives llvmpipe 4.5)"),
    ("Requested OpenGL version", "EGL gave {got}, vfiber needs OpenGL {version}: upgrade Mesa "
                                 "(libgl1-mesa-dri >= 20.3 gives llvmpipe 4.5)"),
)


def _explain_egl(message: str, require: int) -> str:
    got = re.search(r"got version (\d+)", message)
    fill = {"version": _version_text(require), "got": f"OpenGL {_version_text(int(got[1]))}" if got else "less"}
    for needle, hint in _EGL_HINTS:
        if needle in message:
            return hint.format(**fill)
    first = message.strip().splitlines()[0] if message.strip() else "no reason given"
    return f"EGL failed ({first}): {_install('libegl1', 'libegl-mesa0', 'libgl1-mesa-dri')}"


def _create_egl(require: int) -> tuple[moderngl.Context, Callable[[], None]]:
    try:
        _egl()  # checked first so that a missing libEGL gets its own message
    except OSError:
        raise GLContextError(f"EGL could not load libEGL.so.1: {_install('libegl1', 'libegl-mesa0')}") from None
    moderngl = _import_moderngl()
    try:
        ctx = moderngl.create_standalone_context(backend="egl", require=require)
    except Exception as exc:  # glcontext raises bare Exception, moderngl ValueError for the version
        raise GLContextError(_explain_egl(str(exc), require)) from None
    state = _egl_current()
    _our_egl_contexts.add(state.context)
    return ctx, lambda: _egl_make_current(state)


# ------------------------------------------------------------------------------------------- OSMesa
# glcontext 3.1 has no OSMesa backend, so this is a small ctypes one handed to moderngl as `context=`:
# moderngl only needs load_opengl_function/__enter__/__exit__/release from it.

_OSMESA_FORMAT, _OSMESA_DEPTH_BITS, _OSMESA_STENCIL_BITS = 0x22, 0x30, 0x31
_OSMESA_PROFILE, _OSMESA_CORE_PROFILE = 0x33, 0x34
_OSMESA_CONTEXT_MAJOR_VERSION, _OSMESA_CONTEXT_MINOR_VERSION = 0x36, 0x37
_GL_RGBA, _GL_UNSIGNED_BYTE = 0x1908, 0x1401


def _osmesa_library() -> ctypes.CDLL:
    try:
        lib = _open_library(_OSMESA_LIBS)
    except OSError:
        raise GLContextError(f"OSMesa not found (libOSMesa.so.8): {_install('libosmesa6')}") from None
    lib.OSMesaCreateContextExt.restype = ctypes.c_void_p
    lib.OSMesaCreateContextExt.argtypes = [ctypes.c_uint, ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_void_p]
    if hasattr(lib, "OSMesaCreateContextAttribs"):
        lib.OSMesaCreateContextAttribs.restype = ctypes.c_void_p
        lib.OSMesaCreateContextAttribs.argtypes = [ctypes.POINTER(ctypes.c_int), ctypes.c_void_p]
    lib.OSMesaMakeCurrent.restype = ctypes.c_ubyte
    lib.OSMesaMakeCurrent.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_uint, ctypes.c_int, ctypes.c_int]
    lib.OSMesaGetCurrentContext.restype = ctypes.c_void_p
    lib.OSMesaDestroyContext.argtypes = [ctypes.c_void_p]
    lib.OSMesaGetProcAddress.restype = ctypes.c_void_p
    lib.OSMesaGetProcAddress.argtypes = [ctypes.c_char_p]
    return lib


class _OSMesaLoader:
    """One OSMesa context with a 1x1 colour buffer: vfiber draws into framebuffer objects anyway."""

    def __init__(self, lib: ctypes.CDLL, require: int) -> None:
        self.lib = lib
        self.buffer = (ctypes.c_ubyte * 4)()  # must outlive the context: OSMesa keeps the pointer
        handle = None
        if hasattr(lib, "OSMesaCreateContextAttribs"):
            attribs = [_OSMESA_FORMAT, _GL_RGBA, _OSMESA_DEPTH_BITS, 24, _OSMESA_STENCIL_BITS, 8,
                       _OSMESA_PROFILE, _OSMESA_CORE_PROFILE,
                       _OSMESA_CONTEXT_MAJOR_VERSION, require // 100,
                       _OSMESA_CONTEXT_MINOR_VERSION, require // 10 % 10, 0]
            handle = lib.OSMesaCreateContextAttribs((ctypes.c_int * len(attribs))(*attribs), None)
        else:  # OSMesa before Mesa 12: compatibility profile only; the version check below decides
            handle = lib.OSMesaCreateContextExt(_GL_RGBA, 24, 8, 0, None)
        if not handle:
            raise GLContextError(f"OSMesa could not create an OpenGL {_version_text(require)} core context: "
                                 "upgrade libosmesa6 (Mesa >= 20.3)")
        self.handle: int | None = handle
        self.make_current()

    def make_current(self) -> None:
        if not self.lib.OSMesaMakeCurrent(self.handle, self.buffer, _GL_UNSIGNED_BYTE, 1, 1):
            raise GLContextError("OSMesaMakeCurrent failed: reinstall libosmesa6 "
                                 "(apt-get install --reinstall libosmesa6)")

    def load_opengl_function(self, name: str) -> int:
        return self.lib.OSMesaGetProcAddress(name.encode()) or 0

    def __enter__(self) -> None:
        self.make_current()

    def __exit__(self, *args: object) -> None:
        _restore_newest()

    def release(self) -> None:
        if self.handle is None:
            return
        if self.lib.OSMesaGetCurrentContext() == self.handle:
            self.lib.OSMesaMakeCurrent(None, None, 0, 0, 0)
        self.lib.OSMesaDestroyContext(self.handle)
        self.handle = None


def _create_osmesa(require: int) -> tuple[moderngl.Context, Callable[[], None]]:
    lib = _osmesa_library()
    moderngl = _import_moderngl()
    loader = _OSMesaLoader(lib, require)
    try:
        ctx = moderngl.create_context(require=require, standalone=True, context=loader)
    except Exception as exc:
        loader.release()
        got = re.search(r"got version (\d+)", str(exc))
        have = f"OpenGL {_version_text(int(got[1]))}" if got else f"an error ({exc})"
        raise GLContextError(f"OSMesa gave {have}, vfiber needs OpenGL {_version_text(require)}: "
                             "upgrade libosmesa6 (Mesa >= 20.3)") from None
    return ctx, loader.make_current


# ------------------------------------------------------------------------------------------ headless

@dataclass(eq=False)
class HeadlessContext:
    ctx: moderngl.Context
    backend: str                                   # "egl" | "osmesa"
    attempts: list[tuple[str, str]]                # (backend, one-line reason) for those that failed first
    renderer: str                                  # GL_RENDERER, e.g. "llvmpipe (LLVM 15.0.6, 256 bits)"
    version: str                                   # GL_VERSION, e.g. "4.5 (Core Profile) Mesa 22.3.6"
    _make_current: Callable[[], None] = field(repr=False)
    _released: bool = field(default=False, repr=False)

    def make_current(self) -> None:
        self._make_current()

    def release(self) -> None:
        """Free the context and make the newest remaining one current again. Safe to call twice."""
        if self._released:
            return
        self._released = True
        if self in _live:
            _live.remove(self)
        self.ctx.release()
        _restore_newest()

    def __enter__(self) -> HeadlessContext:
        return self

    def __exit__(self, *args: object) -> None:
        self.release()


_live: list[HeadlessContext] = []              # creation order; the last one is current
_outside: Callable[[], None] | None = None     # an EGL context someone made without us, to give back


def _restore_newest() -> None:
    """Best effort: a context that cannot be made current now says so when it is next made current."""
    try:
        if _live:
            _live[-1].make_current()
        elif _outside is not None:
            _outside()
    except (GLContextError, OSError):
        pass


_CREATORS: dict[str, Callable[[int], tuple[Any, Callable[[], None]]]] = {
    "egl": _create_egl,
    "osmesa": _create_osmesa,
}
_PROBE_FIRST = {"osmesa"}  # the backend seen to crash (not fail) in Mesa: always probed in a child first


# ------------------------------------------------------------------------------------ child probes
# A broken driver does not always fail politely: with GALLIUM_DRIVER naming a driver that does not exist,
# EGL fails but OSMesa segfaults inside Mesa, which no Python code can catch. So a backend that is not the
# first choice is first tried in a child process, and only one that came back well is created here.

PROBE_TIMEOUT_S = 30.0


@dataclass(frozen=True)
class ProbeResult:
    backend: str
    ok: bool
    detail: str          # "llvmpipe (...), OpenGL 4.5 ..." when ok; else one line saying what went wrong
    renderer: str = ""
    version: str = ""


_probe_cache: dict[tuple[str, int], ProbeResult] = {}


def probe_backend(name: str, require: int = 450, timeout: float = PROBE_TIMEOUT_S) -> ProbeResult:
    """Create a ``name`` context in a child process and report how that went: a crash (signal) or a hang
    there costs this process nothing. The environment is inherited, so the child sees the same driver."""
    import json
    import signal
    import subprocess
    import sys

    code = ("import json, sys; from app.gl.context import _probe_child; "
            f"print(json.dumps(_probe_child({name!r}, {int(require)})))")
    env = dict(os.environ)
    package_root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [package_root, env.get("PYTHONPATH", "")]))
    try:
        run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout,
                             env=env, stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        return ProbeResult(name, False, f"hung: no context after {timeout:g} s (probed in a child process)")
    except OSError as exc:
        return ProbeResult(name, False, f"could not start a probe process ({exc.strerror or exc})")
    if run.returncode < 0:
        try:
            sig = signal.Signals(-run.returncode).name
        except ValueError:
            sig = f"signal {-run.returncode}"
        return ProbeResult(name, False, f"crashed ({sig}) while creating a context, inside the driver "
                                        "(probed in a child process); check GALLIUM_DRIVER / LIBGL_* settings "
                                        "and reinstall libgl1-mesa-dri")
    last = run.stdout.strip().splitlines()[-1] if run.stdout.strip() else ""
    try:
        answer = json.loads(last)
    except ValueError:
        answer = None
    if run.returncode != 0 or not isinstance(answer, dict):
        why = (run.stderr.strip().splitlines() or [f"exit status {run.returncode}"])[-1]
        return ProbeResult(name, False, f"the probe process failed: {why[:200]}")
    if not answer.get("ok"):
        return ProbeResult(name, False, str(answer.get("error", "failed")))
    return ProbeResult(name, True, f"{answer['renderer']}, OpenGL {answer['version']}", answer["renderer"],
                       answer["version"])


def _probe_child(name: str, require: int) -> dict:
    """Run in the child of probe_backend: make one context, say what it is."""
    try:
        ctx, _ = _CREATORS[name](require)
        renderer, version = _gl_strings(ctx)
    except GLContextError as exc:
        return {"ok": False, "error": str(exc)}
    return {"ok": True, "renderer": renderer, "version": version}


def _probed_well(name: str, require: int) -> ProbeResult:
    key = (name, require)
    if key not in _probe_cache:
        _probe_cache[key] = probe_backend(name, require)
    return _probe_cache[key]


def create_headless(backend: str = "auto", require: int = 450) -> HeadlessContext:
    """A windowless OpenGL ``require`` (e.g. 450) core context: EGL first, then OSMesa.

    ``backend`` is "auto", "egl" or "osmesa"; with "auto", ``$VFIBER_GL_BACKEND`` picks one.
    Raises GLContextError (one line, names the package) when nothing works.
    """
    global _outside
    choice = backend
    if choice == "auto":
        choice = os.environ.get(ENV_BACKEND, "").strip().lower() or "auto"
    if choice != "auto" and choice not in _CREATORS:
        source = f"${ENV_BACKEND}" if backend == "auto" else "backend"
        raise GLContextError(f"unknown GL backend {choice!r} from {source}: use one of {', '.join(BACKENDS)}")
    order = BACKENDS if choice == "auto" else (choice,)

    if not _live:
        _outside = _foreign_egl_context()
    attempts: list[tuple[str, str]] = []
    for index, name in enumerate(order):
        if index > 0 or name in _PROBE_FIRST:  # a fallback is created here only if a child survived it
            probe = _probed_well(name, require)
            if not probe.ok:
                attempts.append((name, probe.detail))
                continue
        try:
            ctx, make_current = _CREATORS[name](require)
            renderer, version = _gl_strings(ctx)
        except GLContextError as exc:
            attempts.append((name, str(exc)))
            _restore_newest()  # a half-made attempt may have taken the current slot
            continue
        hc = HeadlessContext(ctx, name, attempts, renderer, version, make_current)
        _live.append(hc)
        return hc
    if len(attempts) == 1:
        raise GLContextError(attempts[0][1], attempts)
    raise GLContextError("no headless OpenGL: " + "; ".join(f"{b}: {m}" for b, m in attempts), attempts)


def _foreign_egl_context() -> Callable[[], None] | None:
    """An EGL context made current outside this module (a bare moderngl call), so release() can give it back."""
    try:
        state = _egl_current()
    except (OSError, AttributeError):
        return None
    if not state.context or state.context in _our_egl_contexts:
        return None
    return lambda: _egl_make_current(state)


# -------------------------------------------------------------------------------------------- window

class WindowContext(NamedTuple):
    window: Any                           # glfw window handle
    ctx: moderngl.Context
    framebuffer_size: tuple[int, int]     # pixels, which differ from the window size on HiDPI screens


class _GlfwLoader:
    """Load GL functions through glfw, so moderngl never guesses between EGL and GLX for a window."""

    def __init__(self, glfw: Any, window: Any) -> None:
        self.glfw, self.window = glfw, window

    def load_opengl_function(self, name: str) -> int:
        return self.glfw.get_proc_address(name) or 0

    def __enter__(self) -> None:
        self.glfw.make_context_current(self.window)

    def __exit__(self, *args: object) -> None:
        pass

    def release(self) -> None:
        pass  # the viewer owns the window and destroys it with glfw


_NO_DISPLAY = "no display: set DISPLAY or run under xvfb-run (apt-get install xvfb)"


def init_glfw(glfw: Any) -> str | None:
    """``glfw.init()``; None when it worked, else glfw's own reason in words (for messages and the doctor)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            if glfw.init():
                return None
            reasons = [str(w.message) for w in caught]
        except glfw.GLFWError as exc:  # the viewer may have set glfw.ERROR_REPORTING = "raise"
            reasons = [str(exc)]
    # pyGLFW words them "(65550) b'X11: Failed to open display :0'"; keep the words.
    cleaned = [re.sub(r"^\(\d+\) b?['\"](.*)['\"]$", r"\1", r) for r in reasons]
    return "; ".join(cleaned) or "glfw.init failed"


def create_window(width: int, height: int, title: str, visible: bool = True) -> WindowContext:
    """A glfw window with an OpenGL 4.5 core context (3.3 core as fallback) and its moderngl context."""
    try:
        import glfw
    except ImportError as exc:
        raise GLContextError(f"glfw cannot be imported ({exc}): pip install glfw "
                             "(and apt-get install libglfw3 if its bundled library is missing)") from None
    moderngl = _import_moderngl()
    reason = init_glfw(glfw)
    if reason is not None:
        if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"):
            where = os.environ.get("WAYLAND_DISPLAY") or os.environ.get("DISPLAY")
            raise GLContextError(f"no display: {where} cannot be opened ({reason}): check DISPLAY "
                                 "or run under xvfb-run (apt-get install xvfb)")
        raise GLContextError(_NO_DISPLAY)

    window = None
    _egl_unbind()  # before create_window: glfw makes the new context current while creating it
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a refused 4.5 request is expected on older drivers
        for major, minor in ((4, 5), (3, 3)):
            glfw.default_window_hints()
            glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, major)
            glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, minor)
            glfw.window_hint(glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE)
            glfw.window_hint(glfw.OPENGL_FORWARD_COMPAT, True)
            glfw.window_hint(glfw.VISIBLE, visible)
            try:
                window = glfw.create_window(width, height, title, None, None)
            except glfw.GLFWError:
                window = None
            if window:
                break
    if not window:
        glfw.terminate()
        raise GLContextError("the display offers no OpenGL 3.3 core context: install libgl1-mesa-dri "
                             "libglx-mesa0 (apt-get install libgl1-mesa-dri libglx-mesa0)")
    glfw.make_context_current(window)
    try:
        ctx = moderngl.create_context(require=330, context=_GlfwLoader(glfw, window))
    except Exception as exc:
        glfw.destroy_window(window)
        raise GLContextError(f"moderngl cannot use the window's context ({exc}): "
                             "install libgl1-mesa-dri libglx-mesa0") from None
    fb_width, fb_height = glfw.get_framebuffer_size(window)
    return WindowContext(window, ctx, (fb_width, fb_height))
