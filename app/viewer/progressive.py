"""Progressive refinement: which picture the viewer draws next, and drawing it across UI frames.

Speed for accuracy: while something changes (a slider held, the camera moving, the turntable) the fibers
render at the interactive scale (and fast mode by default); after ``refine_delay`` seconds of stillness
the final frame renders at ``quality.render_scale`` in ``quality.mode`` and then accumulates
``quality.supersample``^2 stratified samples. A sample that costs more than ``view.refine_budget_ms`` is drawn in
strips across UI frames (display.StripJob) over the picture that was on screen, with "refining n%" in the
corner, so input, menus and the panel keep running whatever a frame costs.

Before a final frame starts, ``render.budget.estimate`` (the work ``vfiber render`` refuses past a minute
without ``--allow-slow``) is worked out for it: a look that takes more than ``NOTICE_SECONDS`` a frame says so
at the top of the panel and in the stats overlay while it is on screen, and a slow one (``WorkEstimate.slow``)
keeps the interactive preview until the person presses "Render anyway" (script step ``render_anyway``).

The plan (:meth:`Progressive._plan`) is one of None, "new", "sample", "refine", "final-wait" or "held"; the
window loop sleeps unless it is "new", "sample" or "refine". Nothing here touches imgui.
"""

from __future__ import annotations

import math
import statistics
import time
from typing import Any

from ..fibers import fiber_count, ring_layout, tapered
from ..gl.shaders import ShaderError
from ..params import ParamError
from ..render import budget
from .display import CostModel, StripJob, auto_scale, cost_stats, row_weights, supersample_offsets
from .navigate import make_camera
from .state import explicit_bytes, now

IDS_VIEWS = ("fiber ids", "rings", "normals", "depth")
COST_STATS_MAX_PIXELS = 640 * 360       # the occasional cost render for the stats overlay
INTERACTIVE_WHOLE = 1.5                 # interactive frames up to this times auto_budget_ms are drawn whole
NOTICE_SECONDS = 5.0                    # final frames estimated longer than this say so (as vfiber render does)


def _scale_fraction(name: str) -> float | None:
    return None if name == "auto" else float(name.rstrip("%")) / 100.0


class Progressive:
    """The plan of samples and strips across UI frames, the stats it publishes, and script benches (a part
    of ``Viewer``). Reads the scene (loading), the render area (window: ``_viewport_rect``) and hands a
    compile failure to ``_shader_failed`` (hot_reload)."""

    def _init_progressive(self) -> None:
        self._shown_key: tuple | None = None       # what the accumulated image shows
        self._shown_quality = ""
        self._final_wanted = 1                      # samples the final frame accumulates
        self._cost_key: tuple | None = None
        self._estimate_key: tuple | None = None     # what state.stats.estimate was worked out for
        self._look_key: tuple | None = None         # the look "Render anyway" was pressed for
        self._latency_from: float | None = None
        self._ms_per_mpix: float | None = None
        self._bench: dict[str, Any] | None = None
        self._job: dict[str, Any] | None = None     # the sample being refined: key, quality, scale, mode
        self._cost_job: tuple[tuple, StripJob] | None = None    # the overlay's cost render, in strips
        self._weights = None                        # display.row_weights of the frame being drawn
        self._frame_fibers_s = 0.0
        self._sample_started = False                # this UI frame began a sample (its set-up is not UI)

    def _update_counts(self) -> None:
        s, scene = self.state, self.scene
        if scene is None:
            return
        f41, exact = fiber_count(s.params, scene.n_guides)
        per_container = ring_layout(s.params).fibers_per_container
        s.stats.fibers_41, s.stats.fibers_exact = f41, exact
        s.stats.explicit_bytes = explicit_bytes(per_container, scene.n_segments, tapered(s.params))

    # --- render(state): never touches imgui --------------------------------------------------------
    def _update_estimate(self) -> None:
        """The final frame's budget.estimate in plain words (cached by parameters, scene and view size)."""
        s = self.state
        size = self._viewport_rect()[2:]
        values = tuple(s.params.values.items())
        key = (values, id(self.scene), size)
        if key == self._estimate_key:
            return
        self._estimate_key = key
        look = (tuple(kv for kv in values if not kv[0].startswith("camera.")), id(self.scene))
        if look != self._look_key:          # "Render anyway" holds for the look it was pressed for
            self._look_key = look
            s.slow_confirmed = False
        try:
            est = budget.estimate(s.params, self.scene, size)
        except Exception:  # noqa: BLE001 - an estimate never stops the viewer
            est = None
        s.stats.estimate_slow = bool(est and est.slow)
        s.stats.estimate_seconds = est.seconds if est else 0.0
        s.stats.estimate = estimate_text(est, s.stats.gl_renderer) if est and est.seconds > NOTICE_SECONDS else ""

    def _quality(self) -> tuple[str, float, str]:
        """(\"final\" | \"interactive\", scale, mode) for the next sample."""
        s = self.state
        p = s.params
        moving = s.dragging or s.view.turntable or (now() - s.last_change) < s.view.refine_delay
        if not (s.dragging or s.view.turntable):
            # once a gesture ends, not every frame of it: 32,000 segments take ~40 ms to estimate here
            self._update_estimate()
        if self._bench_forces():
            moving = self._bench["quality"] == "interactive"
        elif s.final_held:                  # a slow look: the preview stays until "Render anyway"
            moving = True
        if not moving:
            return "final", p["quality.render_scale"], p["quality.mode"]
        frac = _scale_fraction(s.view.interactive_scale)
        if frac is None:
            rect = self._viewport_rect()
            frac = auto_scale(self._ms_per_mpix, rect[2] * rect[3] * p["quality.render_scale"] ** 2 / 1e6,
                              s.view.auto_budget_ms)
        mode = "fast" if s.view.interactive_mode == "fast" else p["quality.mode"]
        return "interactive", p["quality.render_scale"] * frac, mode

    def _render_size(self, scale: float) -> tuple[int, int]:
        _, _, w, h = self._viewport_rect()
        return max(1, round(w * scale)), max(1, round(h * scale))

    def _plan(self) -> tuple[str | None, tuple]:
        """What the next render should be: (None | \"new\" | \"sample\" | \"refine\" | \"final-wait\" |
        \"held\" (a slow look's preview, waiting for "Render anyway"), key)."""
        s = self.state
        if self.scene is None:
            return None, ()
        quality, scale, mode = self._quality()
        size = self._render_size(scale)
        key = (tuple(s.params.values.items()), s.view.view, size, mode, s.view.frame_path, quality,
               id(self.scene), id(self.programs))
        job = self._job
        if job is not None and self.vp.job is not None:
            if key == job["key"]:
                return "refine", key
            # while things keep moving, an interactive frame is finished before the newest one starts:
            # a picture every few UI frames beats strips of a picture that is never completed
            same_view = key[1:5] == job["key"][1:5] and key[6:] == job["key"][6:]
            if job["quality"] == quality == "interactive" and same_view:
                return "refine", job["key"]
        if key != self._shown_key or self._bench_forces():
            return "new", key
        if quality == "final" and s.view.view in ("shaded", "proxies") and self.vp.samples < self._final_wanted:
            return "sample", key
        if quality == "interactive":
            return ("held" if self.state.final_held else "final-wait"), key
        return None, key

    def final_shown(self) -> bool:
        what, _ = self._plan()
        return what is None and self._shown_quality == "final"

    def render(self) -> bool:
        """Bring the fiber image up to date: start a sample, or draw more of the running one (about
        view.refine_budget_ms of fibers per UI frame). Returns True when it drew fibers."""
        s = self.state
        what, key = self._plan()
        if what == "refine":
            return self._refine()
        if what not in ("new", "sample"):
            self._maybe_cost_stats()
            return False
        quality, scale, mode = self._quality()
        size = key[2]
        self._sample_started = True
        cam = make_camera(s.params, self.scene, size[0] / max(size[1], 1))
        # MSAA happens inside one renderer pass (with the shader's supersampling if both are set); plain
        # supersampling accumulates one stratified sample per frame
        one_pass_aa = quality == "final" and s.params["quality.msaa"] > 0
        if what == "new":
            self._update_counts()
            self._cost_job = None
            walked = self.renderer.visibility(s.params, cam, size, mode) == "walk"
            weights = self._weights = row_weights(self.scene, cam, size, walked)
            model = self.vp.models.get(("draw", mode, one_pass_aa))
            predicted = model.predict(weights.sum()) if model else None
            refines = predicted is None or predicted > self._budget(quality)
            if refines:                       # it will take several UI frames: keep the old picture
                if self.vp.samples == 0 and self.vp.job is None:   # none of this scene yet: a sketch
                    self.vp.sketch(self._viewport_rect()[2:], s.params, cam, self.scene)
                else:
                    self.vp.snapshot(self._viewport_rect()[2:])
            self.vp.resize(size)
            self.vp.invalidate()
            accumulates = quality == "final" and s.view.view in ("shaded", "proxies") and not one_pass_aa
            self._final_wanted = s.params["quality.supersample"] ** 2 if accumulates else 1
            if s.last_edit is not None:
                self._latency_from, s.last_edit = s.last_edit, None
        offsets = supersample_offsets(s.params["quality.supersample"]) if quality == "final" else [(0.0, 0.0)]
        offset = offsets[self.vp.samples % len(offsets)]
        self._job = {"key": key, "quality": quality, "scale": scale, "mode": mode, "cam": cam}
        try:
            if s.view.view == "heat map":
                self._final_wanted = 1
                self.vp.begin_cost(s.params, cam, mode, weights=self._weights)
                return self._refine()
            elif s.view.frame_path == "direct" and not one_pass_aa:
                self.vp.begin_sample(s.params, cam, mode, offset, weights=self._weights)
                return self._refine()
            else:
                timing = self.vp.render_sample(s.params, cam, mode, offset, s.view.frame_path,
                                               with_ids=s.view.view in IDS_VIEWS, antialias=one_pass_aa)
                self._sample_done(timing.best_s, timing.clock)
        except ShaderError as e:
            self._shader_failed(e)
            return False
        except ParamError as e:  # a value this OpenGL cannot do (e.g. more MSAA samples than it has)
            s.errors[e.key or "quality.mode"] = e.bare
            s.status = f"error: {e}"
            self._shown_key = key     # do not retry every frame; a change of any value tries again
            self._job = None
            return False
        return True

    def _refine(self) -> bool:
        """Draw more of the running sample; book it once complete."""
        job = self.vp.job
        t0 = time.perf_counter()
        try:
            done = job is None or self.vp.refine(self._budget(self._job["quality"] if self._job else "final"))
        except ShaderError as e:      # a variant first compiled by this strip
            self.vp.invalidate()
            self._job = None
            self._shader_failed(e)
            return False
        self._frame_fibers_s += time.perf_counter() - t0
        if not done:
            self._show_progress()
            return True
        if self.state.view.view == "heat map" and self.vp.cost_stats is not None:
            self._publish_cost(self.vp.cost_stats)
        self._sample_done(job.spent_s, "wall")
        return True

    def _budget(self, quality: str) -> float:
        """Fiber seconds per UI frame for a sample of this quality."""
        if self._bench_forces():          # a bench of final or interactive frames times whole frames
            return math.inf
        budget = self.state.view.refine_budget_ms / 1000
        if quality == "interactive":
            # an interactive frame near its aim is drawn whole, as a moving picture must be; only one far
            # past it (a frame of seconds) is drawn in strips
            return max(budget, INTERACTIVE_WHOLE * self.state.view.auto_budget_ms / 1000)
        # at least as long as the UI's own part of a frame: where the UI is slow (a loaded machine) strips
        # of 30 ms would leave the refinement a fraction of the time and the frame take many times longer
        ui = statistics.median(self._ui_times) if self._ui_times else 0.0
        return max(budget, ui)

    def _show_progress(self) -> None:
        job = self.vp.job
        st = self.state.stats
        if job is None:
            st.refining = None
            return
        wanted = max(self._final_wanted, 1)
        st.refining = (self.vp.samples + job.fraction) / wanted

    def _sample_done(self, seconds: float, clock: str) -> None:
        s, job = self.state, self._job
        self._job = None
        s.stats.refining = None
        if job is None:
            return
        key, quality, scale, mode = job["key"], job["quality"], job["scale"], job["mode"]
        size = key[2]
        s.stats.render_ms, s.stats.render_clock = seconds * 1000, clock
        mpix = size[0] * size[1] / 1e6
        if mpix > 0 and s.view.view != "heat map":
            rate = seconds * 1000 / mpix
            self._ms_per_mpix = rate if self._ms_per_mpix is None else 0.5 * (self._ms_per_mpix + rate)
        if self._bench is not None:
            self._bench["render"].append(s.stats.render_ms)
            self._bench["size"] = size
        self._shown_key = key
        self._shown_quality = quality
        pct = f"{scale * 100:.0f}%"
        if quality == "final":
            extra = f" {pct}" if scale != 1.0 else ""
            s.stats.label = f"final {mode}{extra}"
        else:
            s.stats.label = f"interactive {pct} {mode}"
        s.stats.render_size = size
        s.stats.samples = (self.vp.samples, self._final_wanted)
        s.stats.depth_range = self.vp.depth_range(job["cam"], self.scene)
        # per-pixel buffers beside the scene's bytes: the renderer's at this size (its own count; None from
        # a renderer that keeps none) and the viewer's (accumulation, uploads, base pictures)
        hook = getattr(self.renderer, "frame_gpu_bytes", None)
        s.stats.frame_gpu_bytes = int(hook(size)) if hook is not None else None
        s.stats.viewer_gpu_bytes = self.vp.buffer_bytes()

    def _heat_max(self) -> float:
        s = self.state
        return s.view.heat_max or max(s.stats.tests_p99, 1.0)

    def _publish_cost(self, stats) -> None:
        st = self.state.stats
        st.tests_per_pixel, st.tests_p99 = stats.mean_tests, stats.p99_tests
        st.covered_pixels, st.cost_size = stats.covered, stats.size
        st.cost_age_s = 0.0

    def _maybe_cost_stats(self) -> None:
        """The overlay's fiber tests per pixel: a small cost render once the view has settled, drawn in
        strips like a slow frame."""
        s = self.state
        if self.vp.cost_stats is not None:
            s.stats.cost_age_s = time.perf_counter() - self.vp.cost_stats.at
        if self.scene is None or self._shown_quality != "final" or self._shown_key == self._cost_key:
            return
        if s.view.view == "heat map":
            self._cost_key = self._shown_key
            return
        if self._cost_job is None or self._cost_job[0] != self._shown_key:
            w, h = self._render_size(1.0)
            k = min(1.0, math.sqrt(COST_STATS_MAX_PIXELS / (w * h)))
            size = (max(1, int(w * k)), max(1, int(h * k)))
            p, mode = s.params, s.params["quality.mode"]
            cam = make_camera(p, self.scene, w / max(h, 1))

            def draw(region):
                return self.renderer.render(p, cam, size, outputs=("cost",), mode=mode, region=region)
            model = self.vp.models.setdefault(("cost", mode), CostModel())
            walked = self.renderer.visibility(p, cam, size, mode) == "walk"
            job = StripJob(size, draw, model, self.ctx.finish, row_weights(self.scene, cam, size, walked))
            self._cost_job = (self._shown_key, job)
        job = self._cost_job[1]
        try:
            done = job.step(self._budget("final"))
        except ShaderError as e:
            self._cost_job = None
            self._shader_failed(e)
            return
        if not done:
            return
        self.vp.cost_stats = stats = cost_stats(job.last.cost, job.size)
        self._publish_cost(stats)
        self._cost_key = self._shown_key
        self._cost_job = None

    # --- benchmarks (script "bench") ---------------------------------------------------------------
    def _bench_forces(self) -> bool:
        """A bench of "final" or "interactive" frames renders a whole new frame every UI frame."""
        return self._bench is not None and self._bench["quality"] in ("final", "interactive")

    def bench_begin(self, quality: str) -> None:
        self._bench = {"quality": quality, "frames": [], "render": [], "fibers": [], "size": None}

    def bench_frames(self) -> int:
        return len(self._bench["frames"]) if self._bench else 0

    def bench_end(self) -> dict[str, Any]:
        b, self._bench = self._bench or {}, None
        frames, render = b.get("frames", []), b.get("render", [])
        self._shown_key = None
        return {"quality": b.get("quality"), "path": self.state.view.frame_path, "size": b.get("size"),
                "frames": len(frames), "frame_ms_median": statistics.median(frames) * 1000 if frames else None,
                "render_ms_median": statistics.median(render) if render else None,
                # fiber strips inside those frames (refining): the frame less this is UI, display and swap
                "fibers_ms_median": statistics.median(b["fibers"]) * 1000 if b.get("fibers") else None,
                "frame_ms": [round(f * 1000, 1) for f in frames]}


def estimate_text(est: budget.WorkEstimate, gl_renderer: str) -> str:
    """What a long frame costs, in the words the panel shows: the throughput behind the seconds was measured
    on llvmpipe, so only there is it "this machine"."""
    where = "on this machine" if "llvmpipe" in gl_renderer.lower() else "on llvmpipe (a GPU is far faster)"
    text = f"this look takes about {budget._duration(est.seconds)} a frame {where}"
    if est.slow:
        text += "; the final frame waits for Render anyway, the preview still draws"
    return f"{text}: {est.summary()}"
