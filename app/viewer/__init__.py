"""The desktop lookdev viewer: a thin shell around the same Renderer the CLI and the tests use.

    state.py     AppState: every value the panels edit (no imgui, no GL)
    gui.py       gui(state): the imgui panels, built from app.params.SPEC; edits state only
    navigate.py  the camera controller: input snapshot -> camera.* parameters
    display.py   the GL side: fiber samples, accumulation, debug views, container proxies
    script.py    scripted sessions (turntables, screenshots, tests); host.py: what it may call on the viewer
    app.py       Viewer, put together from window.py (the loop, input), progressive.py (samples and strips
                 across UI frames), loading.py (scene builds), hot_reload.py and capture.py (screenshots,
                 grabs, turntables); run_viewer(), the entry point of ``vfiber view``

Importing this package does not import imgui or glfw; ``run_viewer`` does, when called.
"""

from __future__ import annotations


def run_viewer(target: str | None, *, script: str | None = None, size=(1280, 720)) -> int:
    from .app import run_viewer as _run

    return _run(target, script=script, size=size)


__all__ = ["run_viewer"]
