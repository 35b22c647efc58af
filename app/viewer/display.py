"""The viewer's GL side: fiber samples from the shared Renderer, accumulation, debug views, proxies.

No imgui here. Two ways to get the renderer's image onto the screen (``ViewSettings.frame_path``):

``direct``
    draw into the renderer's own offscreen targets and sample them as textures: no readback, no upload.
    ``Renderer.render`` always reads back what it draws (``outputs=()`` draws nothing), so this path calls
    the renderer's drawing steps itself (``program``, ``_set_uniforms``, ``_draw``, ``_target``) and clears
    the targets as the renderer does (``clear_targets``). It relies on those private names; if
    they are missing it falls back to ``readback`` by itself and says so.
``readback``
    ``Renderer.render(outputs=...)`` (the public API the CLI and tests use) then upload the numpy
    arrays into textures: the honest, simple way, measured against the other.

Either way the display shader sees the same four textures (accumulated colour, ids, geometry, cost).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import moderngl
import numpy as np

from ..gl.shaders import ProgramCache
from ..params import Params
from ..render.camera import Camera
from ..render.renderer import Frame, Renderer, clear_targets
from ..scene.containers import Scene
from .state import VIEWS

VIEW_CODE = {name: i for i, name in enumerate(VIEWS)}
PROXY_SIDES = 16                                   # must match N_SIDES in glsl/viewer/proxy.vert
PROXY_VERTICES = 4 * PROXY_SIDES + 8
TIMER_WRAP_S = 4.0                                 # a 32-bit nanosecond timer query wraps at 4.29 s

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
        self.direct_ok = True       # Renderer.render(outputs=("draw",)) leaves the frame in renderer.targets
        self.fallback_reason: str | None = None if self.direct_ok else "Renderer internals changed"
        self._accum: moderngl.Framebuffer | None = None
        self._uploads: dict[str, moderngl.Texture] = {}
        self._cost_tex: moderngl.Texture | None = None
        self._empty_vao: dict[int, moderngl.VertexArray] = {}
        self._proxy_buf: moderngl.Buffer | None = None
        self._proxy_vao: dict[int, moderngl.VertexArray] = {}
        self._ids_from: str = "direct"
        self._draw_output: bool | None = None        # does Renderer.render know outputs=("draw",)?
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
    def set_scene(self, scene: Scene) -> None:
        self.renderer.set_scene(scene)
        if self._proxy_buf is not None:
            self._proxy_buf.release()
            self._proxy_buf = None
        for vao in self._proxy_vao.values():
            vao.release()
        self._proxy_vao.clear()
        self.invalidate()

    def invalidate(self) -> None:
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

    # --- one fiber sample --------------------------------------------------------------------------
    def render_sample(self, p: Params, cam: Camera, mode: str, offset: tuple[float, float],
                      path: str, with_ids: bool, antialias: bool = False) -> Timing:
        """Render one sample (one ray per pixel through ``offset``) at ``self.size`` and add it to the
        accumulation. ``antialias``: let the renderer antialias the frame itself (quality.supersample in
        the shader, or quality.msaa) in one pass; that goes through the public readback path."""
        if path == "direct" and (not self.direct_ok or antialias):
            path = "readback"
        ctx = self.ctx
        ctx.finish()
        t0 = time.perf_counter()
        self._before_sample()
        gpu_ns = None
        if path == "direct":
            try:
                with self._timed() as q:
                    self._draw(p, cam, mode, offset)
                gpu_ns = q.ns
            except AttributeError as e:  # the renderer changed under us: say so once and carry on
                self.direct_ok = False
                self.fallback_reason = f"direct frame path unavailable ({e}); using readback"
                return self.render_sample(p, cam, mode, offset, "readback", with_ids)
            color_tex = self.renderer.targets(self.size).color_attachments[0]
            self._ids_from = "direct"
        else:
            outputs = ("color", "ids", "geom") if with_ids else ("color",)
            with self._timed() as q:
                frame = self.renderer.render(p, cam, self.size, outputs=outputs, offset=offset, mode=mode,
                                             antialias=antialias)
                color_tex = self._upload_frame(frame)
            gpu_ns = q.ns
            self._ids_from = "readback"
        self._after_sample(color_tex)
        ctx.finish()
        wall = time.perf_counter() - t0
        self.has_ids = with_ids or path == "direct"
        gpu = gpu_ns / 1e9 if gpu_ns is not None and wall < TIMER_WRAP_S else None
        return Timing(wall, gpu)

    def _draw(self, p: Params, cam: Camera, mode: str, offset) -> None:
        """Draw into the renderer's own targets without reading back (``Renderer.render(outputs=("draw",))``)."""
        self.renderer.render(p, cam, self.size, outputs=("draw",), offset=offset, mode=mode, antialias=False)

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
        if self.samples == 1:
            return self._latest
        return self._accum.color_attachments[0] if self._accum is not None else None

    # --- cost --------------------------------------------------------------------------------------
    def render_cost(self, p: Params, cam: Camera, mode: str, size: tuple[int, int],
                    upload: bool) -> CostStats:
        """A cost render (fiber tests per pixel) through the public API; ``upload`` for the heat map."""
        frame = self.renderer.render(p, cam, size, outputs=("cost",), mode=mode)
        cost = frame.cost
        covered = cost[..., 2] > 0
        tests = cost[..., 0][covered]
        stats = CostStats(float(tests.mean()) if tests.size else None,
                          float(np.percentile(tests, 99)) if tests.size else 0.0,
                          int(covered.sum()), size, time.perf_counter())
        if upload:
            if self._cost_tex is None or self._cost_tex.size != size:
                if self._cost_tex is not None:
                    self._cost_tex.release()
                self._cost_tex = self.ctx.texture(size, 4, dtype="f4")
            self._cost_tex.write(np.ascontiguousarray(cost[::-1]).tobytes())
            self.has_cost = True
        self.cost_stats = stats
        return stats

    # --- display -----------------------------------------------------------------------------------
    def display(self, target: moderngl.Framebuffer, rect: tuple[int, int, int, int], view: str,
                p: Params, cam: Camera | None, scene: Scene | None, heat_max: float) -> None:
        """Draw the current render into ``rect`` (x, y, w, h in the target's pixels, GL origin)."""
        ctx = self.ctx
        target.use()
        ctx.viewport = rect
        ctx.scissor = rect
        ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE | moderngl.BLEND)
        code = VIEW_CODE[view]
        ready = self.has_cost if view == "heat map" else self.samples > 0
        if not ready:
            bg = np.asarray(p["look.background"]) ** (1 / 2.2)
            target.clear(*bg, 1.0, viewport=rect)
            ctx.scissor = None
            return
        prog = self._prog("viewer/display.frag", defines={"VIEW": code})
        dummy = self._dummies()
        shown = self._shown_color() or dummy["f4"]
        # 1:1 (the final frame at render_scale 1): nearest is exact and cheaper than bilinear on llvmpipe
        one_to_one = tuple(self.size) == (rect[2], rect[3])
        shown.filter = (moderngl.NEAREST, moderngl.NEAREST) if one_to_one else (moderngl.LINEAR, moderngl.LINEAR)
        shown.use(0)
        if self._ids_from == "direct" and self.direct_ok and self.samples > 0:
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
                  "uSamples": float(max(self.samples, 1)), "uBackgroundSrgb": bg,
                  "uRings": int(p["fibers.rings"]), "uHeatMax": float(heat_max), "uDim": 0.4,
                  "uDepthRange": self.depth_range(cam, scene)}
        for name, value in values.items():
            if name in prog:
                prog[name].value = value
        self._fullscreen(prog)
        if view == "proxies" and scene is not None and cam is not None:
            self._draw_proxies(scene, cam, rect)
        ctx.scissor = None

    @staticmethod
    def depth_range(cam: Camera | None, scene: Scene | None) -> tuple[float, float]:
        if cam is None or scene is None:
            return (0.0, 1.0)
        lo, hi = scene.bounds()
        centre, radius = 0.5 * (lo + hi), 0.5 * float(np.linalg.norm(hi - lo))
        d = float(np.linalg.norm(centre - cam.position))
        return (max(d - radius, 0.0), d + radius)

    def _draw_proxies(self, scene: Scene, cam: Camera, rect) -> None:
        ctx = self.ctx
        prog = self._prog("viewer/proxy.frag", "viewer/proxy.vert")
        if self._proxy_buf is None:
            self._proxy_buf = ctx.buffer(scene.segments.tobytes())
        vao = self._proxy_vao.get(id(prog))
        if vao is None:
            vao = self._proxy_vao[id(prog)] = ctx.vertex_array(prog, [
                (self._proxy_buf, "4f 4f 4f 4f 4f/i", "in_a", "in_b", "in_c", "in_d", "in_e")])
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
        if self._proxy_buf is not None:
            self._proxy_buf.release()
            self._proxy_buf = None
        for vao in list(self._proxy_vao.values()) + list(self._empty_vao.values()):
            vao.release()
        self._proxy_vao.clear()
        self._empty_vao.clear()


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
