"""The viewer's GL side: fiber samples from the shared Renderer, accumulation, debug views, proxies.

No imgui here. Two ways to get the renderer's image onto the screen (``ViewSettings.frame_path``):

``direct``
    ``Renderer.render(outputs=("draw",))`` draws into the renderer's own offscreen targets
    (``Renderer.targets(size)``) and the display samples them as textures: no readback, no upload.
``readback``
    ``Renderer.render(outputs=...)`` then upload the numpy arrays into textures: the honest, simple way,
    measured against the other.

Either way the display shader sees the same four textures (accumulated colour, ids, geometry, cost).

Slow frames refine across UI frames. A direct sample is a :class:`StripJob`: horizontal strips, top row
first, each drawn with ``Renderer.render(region=...)`` and sized from a :class:`CostModel` so that one UI
frame spends about ``budget_s`` on fibers. Until the sample is complete the display shows the picture
that was on screen before (the *base*, a snapshot; for a new scene a sketch of one line per container)
with the finished strips over it, so input, menus and the panel keep running whatever one frame costs.
A draw has a fixed cost whatever its rectangle (every container's vertices), so no strip is made so
small that the fixed cost is more than MAX_FIXED_SHARE of it: past that, smaller strips mostly add time.
Strips are sized by :func:`row_weights`, the container area per row, because the hair rows of a groom
cost 40x its background rows.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from collections.abc import Callable

import moderngl
import numpy as np

from ..gl.shaders import ProgramCache
from ..params import Params
from ..render.camera import Camera
from ..render.renderer import Frame, Renderer
from ..scene.containers import Scene
from .state import VIEWS

VIEW_CODE = {name: i for i, name in enumerate(VIEWS)}
PROXY_SIDES = 16                                   # must match N_SIDES in glsl/viewer/proxy.vert
PROXY_VERTICES = 4 * PROXY_SIDES + 8
TIMER_WRAP_S = 4.0                                 # a 32-bit nanosecond timer query wraps at 4.29 s
FIRST_STRIP_ROWS = 8                               # a strip whose cost nothing predicts yet
# The most of a strip's time its draw's fixed cost (every container's vertices, whatever the rectangle)
# may take: smaller strips would keep UI frames shorter but make the whole frame take longer, 1 / share
# times its fragment work at worst.
MAX_FIXED_SHARE = 1 / 3

# The heat ramp of app/render/debug_views.py (the CLI's pictures); glsl/viewer/palette.glsl holds the
# same six stops and a test holds the viewer's debug views against debug_views pixel by pixel.
HEAT_STOPS = np.array([[0.05, 0.03, 0.25], [0.1, 0.3, 0.6], [0.1, 0.6, 0.6], [0.5, 0.8, 0.3],
                       [0.98, 0.85, 0.2], [0.9, 0.2, 0.1]])


def supersample_offsets(n: int) -> list[tuple[float, float]]:
    """n x n stratified sub-pixel offsets (pixel units), centre first when n is odd."""
    offs = [((i + 0.5) / n - 0.5, (j + 0.5) / n - 0.5) for j in range(n) for i in range(n)]
    return sorted(offs, key=lambda o: o[0] ** 2 + o[1] ** 2)


@dataclass
class Timing:
    wall_s: float
    gpu_s: float | None          # None when the timer query is unavailable or wrapped

    @property
    def best_s(self) -> float:
        return self.gpu_s if self.gpu_s is not None else self.wall_s

    @property
    def clock(self) -> str:
        return "gpu" if self.gpu_s is not None else "wall"


@dataclass
class CostStats:
    mean_tests: float | None     # fiber tests per container-covered pixel
    p99_tests: float
    covered: int
    size: tuple[int, int]
    at: float


@dataclass
class CostModel:
    """What one draw of a scene costs: a fixed part whatever its rectangle, plus a part per unit of
    :func:`row_weights` (container fragments, roughly) inside it."""

    fixed_s: float | None = None
    per_unit_s: float | None = None

    def predict(self, units: float) -> float | None:
        if self.fixed_s is None or self.per_unit_s is None:
            return None
        return self.fixed_s + self.per_unit_s * units


ROW_WEIGHT_SAMPLE = 32_768       # segments row_weights projects (every n-th past that)


def row_weights(scene: Scene, cam: Camera, size: tuple[int, int], walked: bool = False) -> np.ndarray:
    """The expected cost of each image row (GL order, bottom row first): the area of the container proxies
    that cross it, spread evenly over the rows each one spans, plus a little per pixel. Fibers cost where
    containers overlap, and harolongo's hair rows cost 40x its background rows, so strips sized by pixels
    alone overshoot their budget as they reach the hair. ``walked``: the frame finds its containers by the
    walk (Renderer.visibility), whose cost follows the pixels the hair covers more than the proxies stacked
    on them: the row's proxy area a is taken as w (1 - exp(-a / w)), the pixels that many rectangles
    scattered over the row would cover. (harolongo, 900x701, CPU time of 10-row bands: the walk's time per
    unit of proxy area varied 190x over the bands, per unit of that 5.7x; sintel 10x and 2.2x.)"""
    w, h = int(size[0]), int(size[1])
    # every new frame asks (interactive ones too): past ROW_WEIGHT_SAMPLE segments every stride-th stands for
    # its neighbours (strands are stored root to tip, so a stride samples the whole groom); harolongo's
    # 158,100 took 27-38 ms a frame here, a third of a whole interactive frame at 450x350
    stride = max(1, -(-scene.n_segments // ROW_WEIGHT_SAMPLE))
    seg = scene.segments[::stride]
    rel = np.asarray(scene.origin, np.float64) - cam.position
    m = cam.clip_from_camera(w / max(h, 1))
    ends = []
    for cols in (slice(0, 3), slice(4, 7)):
        p = seg[:, cols] + rel.astype(np.float32)       # float32 is plenty to size strips
        clip = p @ m[:, :3].T + m[:, 3]
        ends.append((clip, clip[:, 3]))
    (ca, wa), (cb, wb) = ends
    front = (wa > 1e-6) & (wb > 1e-6)
    safe_a, safe_b = np.where(front, wa, 1.0), np.where(front, wb, 1.0)
    xa, ya = (ca[:, 0] / safe_a * 0.5 + 0.5) * w, (ca[:, 1] / safe_a * 0.5 + 0.5) * h
    xb, yb = (cb[:, 0] / safe_b * 0.5 + 0.5) * w, (cb[:, 1] / safe_b * 0.5 + 0.5) * h
    focal = 0.5 * h / math.tan(math.radians(cam.fov) / 2)
    r_px = np.maximum(seg[:, 3], seg[:, 7]) * focal / np.minimum(safe_a, safe_b) + 1.0
    y0 = np.clip(np.minimum(ya, yb) - r_px, 0, h)
    y1 = np.clip(np.maximum(ya, yb) + r_px, 0, h)
    area = (np.hypot(xa - xb, ya - yb) + 2 * r_px) * 2 * r_px
    on = front & (y1 > y0)
    lo, hi = np.floor(y0[on]).astype(np.int64), np.ceil(y1[on]).astype(np.int64)
    per_row = stride * area[on] / np.maximum(hi - lo, 1)
    diff = np.bincount(lo, per_row, h + 1) - np.bincount(hi, per_row, h + 1)
    weights = np.cumsum(diff[:h])
    weights += w * 2.0 * stride * (~front).sum()     # a container at the camera covers the whole viewport
    weights = np.maximum(weights, 0.0)
    if walked:
        weights = w * -np.expm1(-weights / w)
    return weights + 0.05 * w                    # and a pixel with no container still costs a little


class StripJob:
    """One frame drawn in horizontal strips across calls to :meth:`step`, top row first.

    ``draw(region)`` draws one strip, (x, y, w, h) in GL pixels, and returns its Frame (or None); the job
    finishes the GPU after each strip to time it and learns ``model`` from the times. ``weights``: the
    expected cost per row (:func:`row_weights`; None: every pixel alike). A frame that fits the budget is
    drawn in one call with ``region=None`` (the whole frame), as without strips.
    """

    def __init__(self, size: tuple[int, int], draw: Callable[[tuple[int, int, int, int] | None], Frame | None],
                 model: CostModel, finish: Callable[[], None], weights: np.ndarray | None = None):
        self.size = (int(size[0]), int(size[1]))
        self.draw = draw
        self.model = model
        self.finish = finish
        w, h = self.size
        weights = np.full(h, float(w)) if weights is None else np.asarray(weights, np.float64)
        self._cum = np.concatenate([[0.0], np.cumsum(weights)])   # rows [a, b) weigh cum[b] - cum[a]
        self.top = h                     # rows [top, height) are drawn (GL rows, bottom first)
        self.spent_s = 0.0               # fiber time over all strips so far
        self.strips = 0
        self.last: Frame | None = None   # what the last strip's draw returned
        self._last_units = 0.0           # the last strip's weight

    @property
    def done(self) -> bool:
        return self.top <= 0

    @property
    def fraction(self) -> float:
        return 1.0 - self.top / max(self.size[1], 1)

    def done_rect(self) -> tuple[int, int, int, int]:
        """The finished part, (x, y, w, h) in the frame's GL pixels."""
        return (0, self.top, self.size[0], self.size[1] - self.top)

    def _units(self, rows: int) -> float:
        return float(self._cum[self.top] - self._cum[self.top - rows])

    def _next_rows(self, budget_s: float) -> int:
        if math.isinf(budget_s):
            return self.top
        m = self.model
        if m.fixed_s is None or m.per_unit_s is None:
            return min(FIRST_STRIP_ROWS, self.top)
        target = max(budget_s, m.fixed_s / MAX_FIXED_SHARE)
        units = (target - m.fixed_s) / max(m.per_unit_s, 1e-15)
        if self._last_units > 0:
            units = min(units, 2.0 * self._last_units)   # the estimate may be off: grow step by step
        lo = int(np.searchsorted(self._cum, self._cum[self.top] - units, side="left"))
        return max(1, min(self.top - lo, self.top))

    def step(self, budget_s: float) -> bool:
        """Draw strips for about ``budget_s`` seconds (at least one). True when the frame is complete."""
        w = self.size[0]
        t_step = time.perf_counter()
        m = self.model
        if m.fixed_s is None and self.strips and not math.isinf(budget_s):
            # the fixed cost: a draw of one pixel (of a finished strip: it comes out the same). Measured
            # after the first strip, so that the first picture is not delayed by it
            t0 = time.perf_counter()
            self.draw((0, self.size[1] - 1, 1, 1))
            self.finish()
            m.fixed_s = time.perf_counter() - t0
            self.spent_s += m.fixed_s
        drawn = 0
        while not self.done:
            rows = self._next_rows(budget_s)
            units = self._units(rows)
            predicted = m.predict(units)
            elapsed = time.perf_counter() - t_step
            if drawn and predicted is not None and elapsed + predicted > budget_s:
                break
            whole = rows == self.top == self.size[1]
            t0 = time.perf_counter()
            self.last = self.draw(None if whole else (0, self.top - rows, w, rows))
            self.finish()
            t = time.perf_counter() - t0
            self.spent_s += t
            self.strips += 1
            drawn += 1
            self._last_units = units
            self.top -= rows
            m.per_unit_s = max(t - (m.fixed_s or 0.0), 0.1 * t) / max(units, 1e-9)
            if time.perf_counter() - t_step >= budget_s or m.fixed_s is None:
                break
        return self.done


class ViewportRenderer:
    """Owns the viewer's GL objects; the Renderer owns the fiber program and its targets."""

    def __init__(self, ctx: moderngl.Context, renderer: Renderer, programs: ProgramCache):
        self.ctx = ctx
        self.renderer = renderer
        self.programs = programs
        self.size: tuple[int, int] = (0, 0)          # current render size (pixels)
        self.samples = 0                              # supersamples accumulated
        self.has_ids = False                          # ids/geom of the current size are valid
        self.has_cost = False
        self.cost_stats: CostStats | None = None
        self.job: StripJob | None = None              # the sample (or heat map) being drawn in strips
        self._job_kind = "sample"                     # "sample": colour, ids, geometry; "cost": the heat map
        self.models: dict[tuple, CostModel] = {}      # per (what, mode): learnt by the strip jobs
        self._bases: list[moderngl.Framebuffer] = []  # two snapshots of the screen, drawn into in turn
        self._base: moderngl.Framebuffer | None = None
        self._shown_args: tuple | None = None         # what display() last drew (view, p, cam, scene, heat)
        self._accum: moderngl.Framebuffer | None = None
        self._uploads: dict[str, moderngl.Texture] = {}
        self._cost_tex: moderngl.Texture | None = None
        self._empty_vao: dict[int, moderngl.VertexArray] = {}
        self._proxy_buf: moderngl.Buffer | None = None
        self._proxy_vao: dict[int, moderngl.VertexArray] = {}
        self._ids_from: str = "direct"
        self._latest: moderngl.Texture | None = None  # the texture holding the newest sample
        self._parking: moderngl.Framebuffer | None = None
        self._query = None
        try:
            self._query = ctx.query(time=True)
        except Exception:  # no timer queries on this driver: wall clock only
            self._query = None

    # --- programs ----------------------------------------------------------------------------------
    def _prog(self, frag: str, vert: str = "stages/fullscreen.vert", defines=None) -> moderngl.Program:
        return self.programs.get(self.ctx, vert, frag, defines)

    def compile_all(self, programs: ProgramCache | None = None) -> None:
        """Compile every viewer program now (hot reload tries a fresh cache with this before swapping)."""
        cache = programs or self.programs
        cache.get(self.ctx, "stages/fullscreen.vert", "viewer/accumulate.frag")
        for code in VIEW_CODE.values():
            cache.get(self.ctx, "stages/fullscreen.vert", "viewer/display.frag", {"VIEW": code})
        cache.get(self.ctx, "viewer/proxy.vert", "viewer/proxy.frag")

    def _fullscreen(self, prog: moderngl.Program) -> None:
        vao = self._empty_vao.get(id(prog))
        if vao is None:
            vao = self._empty_vao[id(prog)] = self.ctx.vertex_array(prog, [])
        vao.render(moderngl.TRIANGLES, vertices=3)

    # --- scene -------------------------------------------------------------------------------------
    def set_scene(self, scene: Scene, bvh=None) -> None:
        self.renderer.set_scene(scene, bvh)
        self.models.clear()          # another scene, another cost per draw
        self.drop_proxies()
        self.invalidate()

    def drop_proxies(self) -> None:
        """Forget the proxies' copy of the segments (the next proxies or sketch draw uploads its scene's)."""
        if self._proxy_buf is not None:
            self._proxy_buf.release()
            self._proxy_buf = None
        for vao in self._proxy_vao.values():
            vao.release()
        self._proxy_vao.clear()

    def invalidate(self) -> None:
        self.job = None
        self.samples = 0
        self._latest = None
        self.has_ids = False
        self.has_cost = False

    def park(self) -> None:
        """Bind a framebuffer that is never released. moderngl keeps the name of the last framebuffer
        used and binds it back when it creates the next one; if that one was released in between, GL
        answers GL_INVALID_OPERATION. So park before releasing anything that may be bound."""
        if self._parking is None:
            self._parking = self.ctx.framebuffer([self.ctx.texture((1, 1), 4)])
        self._parking.use()

    def resize(self, size: tuple[int, int]) -> None:
        """A new render size: drop the renderer's targets of other sizes (they are 37 MB at 720p)."""
        if size == self.size:
            return
        self.park()
        self.renderer.release_targets()
        if self._accum is not None:
            self._accum.color_attachments[0].release()
            self._accum.release()
            self._accum = None
        for tex in self._uploads.values():
            tex.release()
        self._uploads.clear()
        if self._cost_tex is not None:
            self._cost_tex.release()
            self._cost_tex = None
        self.size = size
        self.invalidate()

    # --- one fiber sample ---------------------------------------------------------------------------
    def begin_sample(self, p: Params, cam: Camera, mode: str, offset: tuple[float, float], antialias: bool = False,
                     weights: np.ndarray | None = None) -> StripJob:
        """Start the next sample (one ray per pixel through ``offset``, or the renderer's own antialiasing
        with ``antialias``) at ``self.size`` as strips on the direct path; :meth:`refine` draws them."""
        size = self.size
        if self.samples == 1 and self._latest is not None:
            self._before_sample()            # bank the first sample before the second overwrites it
        self.renderer.compile_programs(p, mode, antialias=antialias)

        def draw(region):
            return self.renderer.render(p, cam, size, outputs=("draw",), offset=offset, mode=mode,
                                        antialias=antialias, region=region)
        model = self.models.setdefault(("draw", mode, antialias), CostModel())
        if weights is None:
            walked = self.renderer.visibility(p, cam, size, mode) == "walk"
            weights = row_weights(self.renderer.scene, cam, size, walked)
        self.job = StripJob(size, draw, model, self.ctx.finish, weights)
        self._job_kind = "sample"
        return self.job

    def begin_cost(self, p: Params, cam: Camera, mode: str, weights: np.ndarray | None = None) -> StripJob:
        """Start the heat map's cost render at ``self.size`` as strips; :meth:`refine` draws them and
        uploads the result once complete."""
        size = self.size
        self.renderer.compile_programs(p, mode, cost=True)

        def draw(region):
            return self.renderer.render(p, cam, size, outputs=("cost",), mode=mode, region=region)
        model = self.models.setdefault(("cost", mode), CostModel())
        if weights is None:
            walked = self.renderer.visibility(p, cam, size, mode) == "walk"
            weights = row_weights(self.renderer.scene, cam, size, walked)
        self.job = StripJob(size, draw, model, self.ctx.finish, weights)
        self._job_kind = "cost"
        return self.job

    def refine(self, budget_s: float) -> bool:
        """Draw the running sample for about ``budget_s`` seconds; True when it is complete (and counted)."""
        job = self.job
        if job is None:
            return True
        if not job.step(budget_s):
            return False
        self.job = None
        if self._job_kind == "cost":
            self._use_cost(job.last.cost, job.size)
            self.samples = 1
            return True
        color_tex = self.renderer.targets(self.size).color_attachments[0]
        self._ids_from = "direct"
        self.has_ids = True
        self._after_sample(color_tex)
        return True

    def render_sample(self, p: Params, cam: Camera, mode: str, offset: tuple[float, float],
                      path: str, with_ids: bool, antialias: bool = False) -> Timing:
        """Render one sample at ``self.size`` now, whole, and add it to the accumulation. ``path``:
        "direct" or "readback" (the module docstring). ``antialias`` with quality.msaa goes through
        readback: the renderer resolves MSAA only into what it reads back."""
        if antialias and p["quality.msaa"] > 0:
            path = "readback"
        ctx = self.ctx
        ctx.finish()
        t0 = time.perf_counter()
        gpu_ns = None
        if path == "direct":
            self.begin_sample(p, cam, mode, offset, antialias)
            with self._timed() as q:
                self.refine(math.inf)
            gpu_ns = q.ns
        else:
            self.job = None
            self._before_sample()
            outputs = ("color", "ids", "geom") if with_ids else ("color",)
            with self._timed() as q:
                frame = self.renderer.render(p, cam, self.size, outputs=outputs, offset=offset, mode=mode,
                                             antialias=antialias)
                color_tex = self._upload_frame(frame)
            gpu_ns = q.ns
            self._ids_from = "readback"
            self._after_sample(color_tex)
            self.has_ids = with_ids
        ctx.finish()
        wall = time.perf_counter() - t0
        gpu = gpu_ns / 1e9 if gpu_ns is not None and wall < TIMER_WRAP_S else None
        return Timing(wall, gpu)

    def _timed(self):
        query = self._query

        class _Q:
            ns: int | None = None

            def __enter__(self_inner):
                if query is not None:
                    query.__enter__()
                return self_inner

            def __exit__(self_inner, *exc):
                if query is not None:
                    query.__exit__(*exc)
                    if exc[0] is None:
                        self_inner.ns = int(query.elapsed)
                return False
        return _Q()

    def _dummies(self) -> dict[str, moderngl.Texture]:
        """1x1 stand-ins bound where a view has nothing (a sampler must never see an unbound unit)."""
        if not hasattr(self, "_dummy"):
            f4 = self.ctx.texture((1, 1), 4, np.zeros(4, np.float32).tobytes(), dtype="f4")
            u4 = self.ctx.texture((1, 1), 4, np.zeros(4, np.uint32).tobytes(), dtype="u4")
            u4.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self._dummy = {"f4": f4, "u4": u4}
        return self._dummy

    def _texture(self, name: str, components: int, dtype: str) -> moderngl.Texture:
        tex = self._uploads.get(name)
        if tex is None:
            tex = self.ctx.texture(self.size, components, dtype=dtype, alignment=1)
            if dtype == "u4":
                tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self._uploads[name] = tex
        return tex

    def _upload_frame(self, frame: Frame) -> moderngl.Texture:
        """numpy (top row first) -> textures (GL rows, bottom first), as the direct path leaves them."""
        rgb = frame.color[::-1]
        rgba = np.concatenate([rgb, np.full(rgb.shape[:2] + (1,), 255, np.uint8)], axis=2)
        color = self._texture("color", 4, "f1")
        color.write(np.ascontiguousarray(rgba).tobytes())
        if frame.ids is not None:
            self._texture("ids", 4, "u4").write(np.ascontiguousarray(frame.ids[::-1]).tobytes())
        if frame.geom is not None:
            self._texture("geom", 4, "f4").write(np.ascontiguousarray(frame.geom[::-1]).tobytes())
        return color

    def _accumulate(self, color: moderngl.Texture) -> None:
        """Add ``color`` to the float accumulation target (additive blending, one fullscreen pass)."""
        ctx = self.ctx
        if self._accum is None:
            self._accum = ctx.framebuffer([ctx.texture(self.size, 4, dtype="f4")])
        self._accum.use()
        ctx.viewport = (0, 0) + self.size
        ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        ctx.enable(moderngl.BLEND)
        ctx.blend_func = moderngl.ONE, moderngl.ONE
        ctx.blend_equation = moderngl.FUNC_ADD
        prog = self._prog("viewer/accumulate.frag")
        color.use(0)
        prog["uColor"].value = 0
        self._fullscreen(prog)
        ctx.disable(moderngl.BLEND)

    def _before_sample(self) -> None:
        """A second sample is about to overwrite the first in the renderer's target: bank the first.
        (A single sample is displayed straight from that target; only supersampling pays for the sum.)"""
        if self.samples == 1 and self._latest is not None:
            if self._accum is not None:
                self._accum.clear(0.0, 0.0, 0.0, 0.0)
            self._accumulate(self._latest)

    def _after_sample(self, color: moderngl.Texture) -> None:
        self.samples += 1
        self._latest = color
        if self.samples > 1:
            self._accumulate(color)

    def _shown_color(self) -> moderngl.Texture | None:
        if self.samples == 1 and (self.job is None or self._accum is None):
            return self._latest
        return self._accum.color_attachments[0] if self._accum is not None else None

    # --- cost --------------------------------------------------------------------------------------
    def render_cost(self, p: Params, cam: Camera, mode: str, size: tuple[int, int],
                    upload: bool) -> CostStats:
        """A cost render (fiber tests per pixel) through the public API; ``upload`` for the heat map."""
        frame = self.renderer.render(p, cam, size, outputs=("cost",), mode=mode)
        if upload:
            return self._use_cost(frame.cost, size)
        self.cost_stats = cost_stats(frame.cost, size)
        return self.cost_stats

    def _use_cost(self, cost: np.ndarray, size: tuple[int, int]) -> CostStats:
        """A cost read-back as the heat map's texture and the overlay's figures."""
        if self._cost_tex is None or self._cost_tex.size != size:
            if self._cost_tex is not None:
                self._cost_tex.release()
            self._cost_tex = self.ctx.texture(size, 4, dtype="f4")
        self._cost_tex.write(np.ascontiguousarray(cost[::-1]).tobytes())
        self.has_cost = True
        self.cost_stats = cost_stats(cost, size)
        return self.cost_stats

    # --- display -----------------------------------------------------------------------------------
    def display(self, target: moderngl.Framebuffer, rect: tuple[int, int, int, int], view: str,
                p: Params, cam: Camera | None, scene: Scene | None, heat_max: float) -> None:
        """Draw the current render into ``rect`` (x, y, w, h in the target's pixels, GL origin). While the
        first sample is still being drawn in strips: the base picture with the finished strips over it."""
        ctx = self.ctx
        self._shown_args = (view, p, cam, scene, heat_max)
        target.use()
        ctx.viewport = rect
        ctx.scissor = rect
        ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE | moderngl.BLEND)
        job = self.job
        if job is not None and self.samples == 0 and view != "heat map":
            self._draw_base(target, rect, p)
            x, y, w, h = job.done_rect()
            if h > 0:       # the finished strips, mapped from render pixels to the viewport's
                sy = rect[3] / max(job.size[1], 1)
                y0 = rect[1] + int(math.floor(y * sy))
                ctx.scissor = (rect[0], y0, rect[2], rect[1] + rect[3] - y0)
                self._draw_view(rect, view, p, cam, scene, heat_max,
                                self.renderer.targets(job.size).color_attachments[0], 1)
            ctx.scissor = None
            return
        ready = self.has_cost if view == "heat map" else self.samples > 0
        if not ready:
            self._draw_base(target, rect, p)
            ctx.scissor = None
            return
        self._draw_view(rect, view, p, cam, scene, heat_max, self._shown_color(), self.samples)
        ctx.scissor = None

    def _draw_base(self, target: moderngl.Framebuffer, rect, p: Params) -> None:
        """The picture shown before the one being drawn (stretched if the viewport changed since), or the
        background when there is none."""
        if self._base is None:
            bg = np.asarray(p["look.background"]) ** (1 / 2.2)
            target.clear(*bg, 1.0, viewport=rect)
            return
        prog = self._prog("viewer/display.frag", defines={"VIEW": VIEW_CODE["shaded"]})
        tex = self._base.color_attachments[0]
        tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
        tex.use(0)
        values = {"uAccum": 0, "uSamples": 1.0, "uBackgroundSrgb": (0.0, 0.0, 0.0)}
        for name, value in values.items():
            if name in prog:
                prog[name].value = value
        self._fullscreen(prog)

    def snapshot(self, size: tuple[int, int]) -> None:
        """Keep what display() last showed (``size``: the viewport's) as the base under the next strips."""
        if self._shown_args is None:
            return
        fbo = self._next_base(size)
        self.display(fbo, (0, 0) + fbo.size, *self._shown_args)   # reads the old base, writes the other
        self._base = fbo

    def sketch(self, size: tuple[int, int], p: Params, cam: Camera, scene: Scene) -> None:
        """A quick first picture of a scene, as the base under its first strips: one line per container,
        along its side from root to tip (the side lines of the proxies view, two vertices a container),
        over the background."""
        fbo = self._next_base(size)
        ctx = self.ctx
        fbo.use()
        ctx.viewport = (0, 0) + fbo.size
        ctx.scissor = None
        ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE | moderngl.BLEND)
        bg = np.asarray(p["look.background"]) ** (1 / 2.2)
        fbo.clear(*bg, 1.0)
        prog, vao = self._proxy_program(scene)
        prog["uSceneFromCamera"].value = tuple(scene.origin - cam.position)
        prog["uClipFromCamera"].write(cam.clip_from_camera(fbo.size[0] / max(fbo.size[1], 1)).T.copy().tobytes())
        if "uAlpha" in prog:
            prog["uAlpha"].value = 1.0
        vao.render(moderngl.LINES, vertices=2, first=4 * PROXY_SIDES, instances=scene.n_segments)
        self._base = fbo

    def _next_base(self, size: tuple[int, int]) -> moderngl.Framebuffer:
        """The base framebuffer not shown now (display reads the other), at ``size``."""
        size = (max(int(size[0]), 1), max(int(size[1]), 1))
        if not self._bases or self._bases[0].size != size:
            self._release_bases()       # (a resized viewport starts from the background)
            self._bases = [self.ctx.framebuffer([self.ctx.texture(size, 4, dtype="f1")]) for _ in range(2)]
        return self._bases[1] if self._base is self._bases[0] else self._bases[0]

    def _release_bases(self) -> None:
        self.park()
        for fbo in self._bases:
            fbo.color_attachments[0].release()
            fbo.release()
        self._bases, self._base = [], None

    def buffer_bytes(self) -> int:
        """Bytes of the viewer's own per-pixel buffers: accumulation, uploads, cost, the two bases."""
        total = 0
        texs = list(self._uploads.values()) + [f.color_attachments[0] for f in self._bases]
        if self._accum is not None:
            texs.append(self._accum.color_attachments[0])
        if self._cost_tex is not None:
            texs.append(self._cost_tex)
        for t in texs:
            total += t.width * t.height * t.components * {"f1": 1, "u4": 4, "f4": 4}.get(t.dtype, 4)
        return total

    def _draw_view(self, rect, view: str, p: Params, cam: Camera | None, scene: Scene | None, heat_max: float,
                   shown: moderngl.Texture | None, samples: int) -> None:
        prog = self._prog("viewer/display.frag", defines={"VIEW": VIEW_CODE[view]})
        dummy = self._dummies()
        shown = shown or dummy["f4"]
        # 1:1 (the final frame at render_scale 1): nearest is exact and cheaper than bilinear on llvmpipe
        one_to_one = tuple(self.size) == (rect[2], rect[3])
        shown.filter = (moderngl.NEAREST, moderngl.NEAREST) if one_to_one else (moderngl.LINEAR, moderngl.LINEAR)
        shown.use(0)
        if self._ids_from == "direct" and (self.samples > 0 or self.job is not None):
            fbo = self.renderer.targets(self.size)
            ids, geom = fbo.color_attachments[1], fbo.color_attachments[2]
            ids.filter = (moderngl.NEAREST, moderngl.NEAREST)   # integer textures sample only NEAREST
        else:
            ids = self._uploads.get("ids") or dummy["u4"]
            geom = self._uploads.get("geom") or dummy["f4"]
        ids.use(1)
        geom.use(2)
        (self._cost_tex if self._cost_tex is not None else dummy["f4"]).use(3)
        bg = tuple(float(x) for x in np.round(np.clip(p["look.background"], 0, 1) ** (1 / 2.2) * 255) / 255)
        values = {"uAccum": 0, "uIds": 1, "uGeom": 2, "uCost": 3,
                  "uSamples": float(max(samples, 1)), "uBackgroundSrgb": bg,
                  "uRings": int(p["fibers.rings"]), "uHeatMax": float(heat_max), "uDim": 0.4,
                  "uDepthRange": self.depth_range(cam, scene)}
        for name, value in values.items():
            if name in prog:
                prog[name].value = value
        self._fullscreen(prog)
        if view == "proxies" and scene is not None and cam is not None:
            self._draw_proxies(scene, cam, rect)

    @staticmethod
    def depth_range(cam: Camera | None, scene: Scene | None) -> tuple[float, float]:
        if cam is None or scene is None:
            return (0.0, 1.0)
        lo, hi = scene.bounds()
        centre, radius = 0.5 * (lo + hi), 0.5 * float(np.linalg.norm(hi - lo))
        d = float(np.linalg.norm(centre - cam.position))
        return (max(d - radius, 0.0), d + radius)

    def _proxy_program(self, scene: Scene) -> tuple[moderngl.Program, moderngl.VertexArray]:
        ctx = self.ctx
        prog = self._prog("viewer/proxy.frag", "viewer/proxy.vert")
        if self._proxy_buf is None:
            self._proxy_buf = ctx.buffer(scene.segments.tobytes())
        vao = self._proxy_vao.get(id(prog))
        if vao is None:
            vao = self._proxy_vao[id(prog)] = ctx.vertex_array(prog, [
                (self._proxy_buf, "4f 4f 4f 4f 4f/i", "in_a", "in_b", "in_c", "in_d", "in_e")])
        return prog, vao

    def _draw_proxies(self, scene: Scene, cam: Camera, rect) -> None:
        ctx = self.ctx
        prog, vao = self._proxy_program(scene)
        w, h = rect[2], rect[3]
        prog["uSceneFromCamera"].value = tuple(scene.origin - cam.position)
        prog["uClipFromCamera"].write(cam.clip_from_camera(w / max(h, 1)).T.copy().tobytes())
        if "uAlpha" in prog:
            prog["uAlpha"].value = 0.9
        ctx.enable(moderngl.BLEND)
        ctx.blend_func = moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA
        vao.render(moderngl.LINES, vertices=PROXY_VERTICES, instances=scene.n_segments)
        ctx.disable(moderngl.BLEND)

    # --- offscreen (screenshots of debug views, tests) ---------------------------------------------
    def display_offscreen(self, size: tuple[int, int], view: str, p: Params, cam: Camera,
                          scene: Scene, heat_max: float) -> np.ndarray:
        """The current render displayed into an offscreen RGBA8 target; (H, W, 3) uint8, top row first."""
        tex = self.ctx.texture(size, 4, dtype="f1")
        fbo = self.ctx.framebuffer([tex])
        try:
            self.display(fbo, (0, 0) + tuple(size), view, p, cam, scene, heat_max)
            raw = fbo.read(components=3, alignment=1)
        finally:
            self.park()
            fbo.release()
            tex.release()
        return np.frombuffer(raw, np.uint8).reshape(size[1], size[0], 3)[::-1].copy()

    def release(self) -> None:
        self.resize((0, 0))
        self._release_bases()
        if self._proxy_buf is not None:
            self._proxy_buf.release()
            self._proxy_buf = None
        for vao in list(self._proxy_vao.values()) + list(self._empty_vao.values()):
            vao.release()
        self._proxy_vao.clear()
        self._empty_vao.clear()


def cost_stats(cost: np.ndarray, size: tuple[int, int]) -> CostStats:
    """Fiber tests per container-covered pixel of a cost read-back (mean and 99th percentile)."""
    covered = cost[..., 2] > 0
    tests = cost[..., 0][covered]
    return CostStats(float(tests.mean()) if tests.size else None,
                     float(np.percentile(tests, 99)) if tests.size else 0.0,
                     int(covered.sum()), size, time.perf_counter())


def render_still(renderer: Renderer, p: Params, cam: Camera, size: tuple[int, int]) -> np.ndarray:
    """The render without UI, as the command line makes it: ``Renderer.render_quality`` (render_scale,
    supersample and msaa all honoured by the renderer). (H, W, 3) uint8, top row first."""
    if hasattr(renderer, "render_quality"):
        return renderer.render_quality(p, cam, tuple(size), outputs=("color",)).color
    # an older renderer: n x n single-ray frames averaged, render_scale applied here
    scale = p["quality.render_scale"]
    w, h = int(size[0]), int(size[1])
    rw, rh = max(1, round(w * scale)), max(1, round(h * scale))
    acc = np.zeros((rh, rw, 3), np.float64)
    offsets = supersample_offsets(p["quality.supersample"])
    for off in offsets:
        acc += renderer.render(p, cam, (rw, rh), outputs=("color",), offset=off).color
    img = np.clip(np.round(acc / len(offsets)), 0, 255).astype(np.uint8)
    if (rw, rh) != (w, h):
        from PIL import Image
        img = np.asarray(Image.fromarray(img).resize((w, h), Image.BILINEAR))
    return img


def auto_scale(ms_per_megapixel: float | None, megapixels: float, budget_ms: float) -> float:
    """The interactive scale that brings a render near ``budget_ms`` (in eighths, 1/8 .. 1)."""
    if not ms_per_megapixel or megapixels <= 0:
        return 0.5
    s = math.sqrt(budget_ms / (ms_per_megapixel * megapixels))
    return float(np.clip(math.floor(s * 8) / 8, 0.125, 1.0))
