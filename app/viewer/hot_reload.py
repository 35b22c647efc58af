"""Shader hot reload: the GLSL files on screen are polled, and a change compiles everything with a fresh
program cache; the swap happens only when all of it compiles, so a typo leaves the last good program on
screen and its error in the panel."""

from __future__ import annotations

import time

from ..gl.shaders import ProgramCache, ShaderError
from .window import SHADER_POLL_S


class HotReload:
    """Watching and reloading the shaders (a part of ``Viewer``). A reload sets ``_shown_key`` to None so
    that progressive refinement draws the picture again with the new programs."""

    def _init_hot_reload(self) -> None:
        self._watch: ProgramCache = self.programs   # the cache whose files are watched for hot reload
        self._fallback: ProgramCache | None = None  # the programs before the last reload
        self._last_shader_poll = 0.0

    def _poll_shaders(self) -> None:
        t = time.perf_counter()
        if t - self._last_shader_poll < SHADER_POLL_S:
            return
        self._last_shader_poll = t
        if not self._watch.sources_changed():
            return
        self.reload_shaders()

    def reload_shaders(self) -> bool:
        """Compile everything on screen with a fresh cache; swap only when all of it compiles."""
        s = self.state
        fresh = ProgramCache(self.programs.root)
        self._watch = fresh
        old = self.renderer.programs
        self.renderer.programs = fresh
        try:
            modes = {s.params["quality.mode"], "fast"}
            for mode in modes:
                self.renderer.compile_programs(s.params, mode)
            self.renderer.compile_programs(s.params, s.params["quality.mode"], cost=True)
            self.vp.compile_all(fresh)
        except ShaderError as e:
            self.renderer.programs = old
            s.shader_error = str(e)   # shown in the panel, not as a dialog: saving a file is not an event
            s.status = "error: shader reload failed (see the panel); the last good program stays on screen"
            return False
        self._fallback = self.programs
        self.programs = fresh
        self.vp.programs = fresh
        s.shader_error = None
        s.status = "shaders reloaded"
        self._shown_key = None
        return True

    def _shader_failed(self, e: ShaderError) -> None:
        """A variant that was not compiled ahead failed: go back to the previous programs if we have them."""
        s = self.state
        s.shader_error = str(e)
        s.status = "error: shader compile failed (see the panel)"
        if self._fallback is not None:
            self.programs = self.renderer.programs = self.vp.programs = self._fallback
            self._fallback = None
            self._shown_key = None
