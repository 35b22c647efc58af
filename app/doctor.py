"""``vfiber doctor``: what OpenGL this machine offers vfiber, and what to install when it offers none.

Every probe is fenced: the report is for a person whose setup is broken, so it must never raise.
"""

from __future__ import annotations

import os
import platform
import re
import subprocess
import sys
from collections.abc import Callable

_WIDTH = 10  # label column


def _line(label: str, text: str) -> str:
    return f"  {label:<{_WIDTH}} {text}"


def _fenced(probe: Callable[[], list[str]], label: str) -> list[str]:
    try:
        return probe()
    except Exception as exc:  # noqa: BLE001 - a doctor reports, it does not crash
        return [_line(label, f"probe failed: {type(exc).__name__}: {exc}")]


def _versions() -> list[str]:
    lines = [_line("python", f"{platform.python_version()} ({sys.executable})")]
    try:
        import moderngl

        try:
            import glcontext

            extra = f" (glcontext {glcontext.__version__})"
        except ImportError:
            extra = " (glcontext missing: pip install glcontext)"
        lines.append(_line("moderngl", f"{moderngl.__version__}{extra}"))
    except ImportError as exc:
        lines.append(_line("moderngl", f"cannot be imported ({exc}): pip install moderngl"))
    return lines


def _backends(mesa: list[str], working: list[str]) -> list[str]:
    """Every backend, each probed in a child process: a driver that segfaults (GALLIUM_DRIVER naming a
    driver that does not exist makes OSMesa do that) costs one line of the report, not the report."""
    from app.gl.context import BACKENDS, ENV_BACKEND, probe_backend

    lines = []
    for name in BACKENDS:
        probe = probe_backend(name)
        if not probe.ok:
            lines.append(_line(name, f"no: {probe.detail}"))
            continue
        lines.append(_line(name, f"ok: {probe.detail}"))
        working.append(name)
        found = re.search(r"Mesa (\S+)", probe.version)
        if found and not mesa:
            mesa.append(found[1])

    forced = os.environ.get(ENV_BACKEND, "").strip().lower()
    if forced:
        state = "works" if forced in working else "does NOT work"
        lines.append(_line("chosen", f"{forced}, forced by {ENV_BACKEND}={forced} ({state})"))
        if forced not in working:
            working.clear()  # renders will use the forced backend only
    elif working:
        why = "the first in auto order" if working[0] == BACKENDS[0] else f"{BACKENDS[0]} failed"
        lines.append(_line("chosen", f"{working[0]} ({why}: {' -> '.join(BACKENDS)})"))
    else:
        lines.append(_line("chosen", "none: renders and tests cannot run; install one of the packages above"))
    return lines


def _display() -> list[str]:
    where = os.environ.get("WAYLAND_DISPLAY") or os.environ.get("DISPLAY")
    if not where:
        return [_line("display", "none: the viewer needs DISPLAY (or run it under xvfb-run); "
                                 "renders and tests do not")]
    import glfw

    from app.gl.context import init_glfw

    reason = init_glfw(glfw)
    if reason is not None:
        return [_line("display", f"{where} cannot be opened ({reason})")]
    platform_name = {getattr(glfw, "PLATFORM_X11", -1): "X11", getattr(glfw, "PLATFORM_WAYLAND", -2): "Wayland"}
    kind = platform_name.get(glfw.get_platform(), "") if hasattr(glfw, "get_platform") else ""
    glfw.terminate()
    return [_line("display", f"ok: {where} {kind}".rstrip() + " (glfw init works; the viewer can open)")]


def _glslang() -> list[str]:
    from app.gl.shaders import glslang_path

    exe = glslang_path()
    if exe is None:
        return [_line("glslang", "glslangValidator not found (optional shader lint): apt-get install glslang-tools")]
    out = subprocess.run([exe, "--version"], capture_output=True, text=True, timeout=10).stdout
    version = out.splitlines()[0].split(":", 1)[-1].strip() if out else "version unknown"
    return [_line("glslang", f"{exe} ({version})")]


def _mesa(mesa: list[str]) -> list[str]:
    package = ""
    try:
        result = subprocess.run(["dpkg-query", "-W", "-f", "${Version}", "libgl1-mesa-dri"],
                                capture_output=True, text=True, timeout=10)
        if result.returncode == 0 and result.stdout:
            package = f" (libgl1-mesa-dri {result.stdout.strip()})"
    except (OSError, subprocess.SubprocessError):
        pass
    version = mesa[0] if mesa else "unknown: no context reported one"
    return [_line("mesa", version + package)]


def doctor_report(working: list[str] | None = None) -> list[str]:
    """One line per fact, for people and for bug reports. Never raises. ``working`` collects the backends
    that work (for the exit status)."""
    mesa: list[str] = []
    working = [] if working is None else working
    lines = ["vfiber doctor"]
    lines += _fenced(_versions, "versions")
    lines += _fenced(lambda: _backends(mesa, working), "backends")
    lines += _fenced(_display, "display")
    lines += _fenced(_glslang, "glslang")
    lines += _fenced(lambda: _mesa(mesa), "mesa")
    return lines


def main(argv: list[str] | None = None) -> int:
    """Exit 0 when some backend works (renders can run), 1 when none does."""
    working: list[str] = []
    print("\n".join(doctor_report(working)), flush=True)
    return 0 if working else 1


if __name__ == "__main__":
    raise SystemExit(main())
