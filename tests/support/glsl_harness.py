"""Run a test's own fragment shader, which may #include the project's glsl/, over a small float target.

The tests that hold a GLSL function to its numpy twin each draw one full-screen triangle and read every
pixel back; this is that draw, once.
"""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path

import moderngl
import numpy as np

from app.gl.shaders import ProgramCache, glsl_root
from tests.support.paths import GLSL_HARNESS


def run_fragment(ctx: moderngl.Context, source: str, size: tuple[int, int],
                 setup: Callable[[moderngl.Program], None] | None = None) -> np.ndarray:
    """Draw ``source`` (a fragment shader writing ``location = 0``) over ``size`` = (W, H) RGBA32F pixels;
    ``setup(program)`` sets its uniforms. Returns the pixels, (H, W, 4) float64, row 0 at gl_FragCoord.y 0.5.

    The shader is compiled from a copy of glsl/ with it beside the project's files, so its #include lines
    resolve as the renderer's do and a compile error names the harness's line."""
    W, H = size
    tmp = Path(tempfile.mkdtemp())
    try:
        shutil.copytree(glsl_root(), tmp / "glsl")
        (tmp / "glsl" / "test_harness.frag").write_text(source)
        (tmp / "glsl" / "fullscreen.vert").write_text((GLSL_HARNESS / "fullscreen.vert").read_text())
        prog = ProgramCache(tmp / "glsl").get(ctx, "fullscreen.vert", "test_harness.frag")
        if setup is not None:
            setup(prog)
        tex = ctx.texture((W, H), 4, dtype="f4")
        fbo = ctx.framebuffer([tex])
        try:
            fbo.use()
            ctx.viewport = (0, 0, W, H)
            ctx.disable(moderngl.CULL_FACE | moderngl.DEPTH_TEST | moderngl.BLEND)
            ctx.vertex_array(prog, []).render(vertices=3)
            return np.frombuffer(tex.read(), np.float32).reshape(H, W, 4).astype(np.float64)
        finally:
            ctx.framebuffer(ctx.renderbuffer((1, 1))).use()
            fbo.release()
            tex.release()
    finally:
        shutil.rmtree(tmp)
