"""The virtual-fiber renderer: container proxies + the traversal shader + offscreen targets.

One renderer serves the command line, the viewer, the tests and the benchmarks. It never imports glfw: it
draws into whatever moderngl context it is given.

Per frame it draws one fullscreen pass (stages/raycast.frag): each pixel's ray walks a hierarchy of the
container segments (bvh.py, geometry/bvh.glsl) nearest box first and traverses each container's virtual
fibers until the next box starts behind the nearest fiber found, so a frame costs its covered pixels and
the containers in front of their fibers, not every container that overlaps them on screen. A pixel that
needs more containers than one draw holds keeps its place in a per-pixel state image and the renderer
draws again until none is left. Outputs (all read back top row first):

    color  (H, W, 3) uint8    shaded, tone-mapped sRGB
    ids    (H, W, 4) uint32   guide + 1 (0 = no fiber), ring, fiber, segment
    geom   (H, W, 4) float32  world normal xyz, distance along the ray (0 on a miss)
    cost   (H, W, 4) float32  fiber tests, arcs visited, containers entered and traversed, loop passes
                              (summed over the pixel's draws: the work actually done)
    walk   (H, W, 4) float32  candidate containers traversed, box tests, walks, walks that ran out
    iters  (H, W)    float32  the most loop passes any single shader invocation ran
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import moderngl
import numpy as np

from .. import fibers
from . import look
from ..gl.shaders import ProgramCache
from ..params import ParamError, Params
from ..scene.containers import Scene, joint_slope
from .bvh import ContainerBvh, HierarchyTooLarge, build_bvh, bvh_words
from .camera import Camera

MAX_RINGS = fibers.MAX_RINGS
# llvmpipe ends all loops of a fragment shader silently once they have made this many passes through loop
# headers in all; a loop's final, failing test is a pass too, so a loop of n iterations costs n + 1. The
# count is kept per SIMD batch of fragments, not per fragment: where lanes take different branches, the
# batch runs the loops of every branch taken, and a loop as often as its longest lane needs.
LOOP_CAP = 65_535
BRUTE_CHUNK = 60_000              # fibers per brute-force draw: stays under LOOP_CAP with 64 rings
MAX_SUB = fibers.MAX_SUB          # chord pieces per arc of a curved-fiber ring (glsl/fibers/curved.glsl)
# A ray visits a ring of curved fibers on one or two arcs (going in, coming out: glsl/fibers/shaped.glsl);
# brute force draws by ring order, so a batch visits each ring on at most two; it tests every fiber of its
# chunk on each of up to MAX_SUB chord pieces of an arc, one pass of the candidate loop each plus each
# piece's headers (with curl or frizz three per 32 candidates: SHAPED_SCREEN's chunks). 16 passes per ring
# pay for the band, arc, piece and canary loops. The chunk is the one the old per-fiber chord loop used
# (four arcs of MAX_SUB + 2 passes a fiber), which leaves ample room: a ring with m fibers in the draw costs
# a visit at most MAX_SUB (m (1 + 3/32) + 5) + 1 passes, so two visits of every ring of a full chunk take
# under 35 per fiber plus 162 per ring, 42,000 at most with MAX_RINGS rings.
BRUTE_CHUNK_SHAPED = (LOOP_CAP - 16 * MAX_RINGS) // (4 * (MAX_SUB + 2))
TWIST_PATTERNS, CURL_PATTERNS = fibers.TWIST_PATTERNS, fibers.CURL_PATTERNS
SHADING_MODELS = {"kajiya_kay": 0, "marschner": 1}
SHADOW_MODES = {"off": 0, "density": 1, "traced": 2}
# standard MSAA sample positions (1/16 px about the pixel centre, y up), as GL implementations place them
# (llvmpipe's 4x the same). quality.msaa casts one single-ray frame at each (render): a multisample
# target shades a proxy fragment once for all its samples, which leaves the grain of sub-pixel fibers
# inside a container as it is, and llvmpipe stores 2x as 4 samples, so a 2-bit mask covered half a pixel.
MSAA_PATTERNS = {
    2: [(4, 4), (-4, -4)],
    4: [(-2, -6), (6, -2), (-6, 2), (2, 6)],
    8: [(1, -3), (-1, 3), (5, 1), (-3, -5), (-5, 5), (-7, -1), (3, 7), (7, -7)],
}
MODES = {"fast": 0, "exact": 1, "brute": 2}
# quality.filter = coverage (glsl/fibers/coverage.glsl): candidates per ring visit of the coverage scan, and
# the loop passes it may spend, 2 visits a ring plus each visit's final test
COVER_CAP = 48
COVER_LIGHT_NODES = 5             # the medium's points across a ring's arc for the key light (coverage.glsl)

# The proxy rectangle's corners as two triangles (glsl/stages/container.vert places them per segment).
_QUAD = np.array([[0, 0], [1, 0], [1, 1], [0, 0], [1, 1], [0, 1]], dtype=np.float32)
WALK_CAP = 4096                   # box tests per walk (glsl/geometry/bvh.glsl)
# The walk reads the scene's words (hierarchy nodes, leaf order, segments) from images of WORD_ROW texels a
# row (geometry/bvh.glsl: WORD_ROW_SHIFT): llvmpipe gathers an image per SIMD batch, a storage buffer one lane
# and one component at a time. Image units: NODE_UNIT, ORDER_UNIT, SEGMENT_UNIT (bvh.glsl's bindings).
WORD_ROW = 4096
NODE_UNIT, ORDER_UNIT, SEGMENT_UNIT = 7, 8, 9
LIST_UNITS = (10, 11)             # walk.frag: the list of pixels a draw walks and the one it appends to
NEAREST_UNIT = 12                 # container.frag: the nearest hit so far per pixel, for the proxies
VISIBILITY = ("auto", "proxies", "walk")
# auto: the walk once the proxies would stack this many layers per covered pixel (proxy_layers). Measured
# on llvmpipe, 640x360 exact, CPU time per frame (one process, 7 alternated frames, median), walk over
# proxies: straight (1.0 layers) 2.04, default preset (2.5) 1.18, curly-1 (3.8) 1.26, ellipsoid (4.3) 1.31,
# carpet (5.9) 0.87, fur-ball (11.7) 0.48; sintel 0.35, harolongo 0.04 (docs/performance.md, "Two ways to
# find a pixel's containers"). The walk wins from ~5 layers in exact mode now, but the threshold stays at 8:
# the walk's fast mode takes the first container with a hit in walk order, the proxies' keeps the nearest
# of every container's first hit, so walking carpet would move its fast-mode ids (20.4% of its hit pixels
# differ from exact walked, 14.5% by proxies).
WALK_LAYERS = 8.0
LAYER_SAMPLE = 32_768             # segments proxy_layers counts (every n-th past that)
MAX_DRAWS = 512                   # draws of one sample and fiber range before the renderer gives up
COVERAGE_LEVEL = 6                # hierarchy level whose node boxes mark the pixels to walk (<= 64 boxes)
WALK_DEPTH, RESOLVE_DEPTH, EMPTY_DEPTH = 0.5, 0.75, 0.9     # window depths of the fullscreen passes (_pass)


@dataclass
class Frame:
    color: np.ndarray | None = None
    coverage: np.ndarray | None = None     # (H, W) float32: fraction of the pixel covered by fibers
    ids: np.ndarray | None = None
    geom: np.ndarray | None = None
    cost: np.ndarray | None = None
    iters: np.ndarray | None = None
    walk: np.ndarray | None = None
    draws: int = 0
    unfinished: int = 0     # pixels still short of their nearest fiber after MAX_DRAWS (0 unless broken)

    @property
    def hit(self) -> np.ndarray:
        return self.ids[..., 0] > 0


def light_direction(p: Params) -> np.ndarray:
    az, el = math.radians(p["look.light_azimuth"]), math.radians(p["look.light_elevation"])
    return np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])


class Renderer:
    COLOR_DTYPE = "f1"      # the picture's target: premultiplied RGBA8 (extremes bench: float32, NaN shows)

    def __init__(self, ctx: moderngl.Context, programs: ProgramCache | None = None):
        self.ctx = ctx
        self.programs = programs or ProgramCache()
        self.scene: Scene | None = None
        self.bvh: ContainerBvh | None = None
        self._buffers: dict[str, moderngl.Buffer] = {}
        self._words: dict[str, moderngl.Texture] = {}       # the walk's images of the scene (word_image)
        self._progress = ctx.buffer(reserve=4)
        self._quad = ctx.buffer(_QUAD.tobytes())
        self._vaos: dict[tuple, moderngl.VertexArray] = {}
        self._layers: tuple[tuple, float] | None = None     # (camera and size, proxy_layers) of the last frame
        self._targets: dict[tuple, moderngl.Framebuffer] = {}
        self._sampled: dict[tuple, tuple] = {}      # the last antialiased frame per size (_keep_outside)
        self._parking = ctx.framebuffer(ctx.renderbuffer((1, 1)))   # bound while targets are released

    # --- scene -------------------------------------------------------------------------------------
    def set_scene(self, scene: Scene, bvh: ContainerBvh | None = None) -> None:
        """Upload the containers and their hierarchy once (``bvh``: build_bvh(scene) made elsewhere, e.g. in
        the viewer's loading thread; None: built here). Nothing here depends on how many fibers are drawn:
        five vec4 per segment for the proxies and five for the walk, four per hierarchy node, one index per
        segment for the walk and one for the proxies' draw order."""
        for buf in (*self._buffers.values(), *self._words.values()):
            buf.release()
        for vao in self._vaos.values():
            vao.release()
        self._vaos.clear()
        self._layers = None
        self._proxy_order_from = None
        self.scene = scene
        self.bvh = bvh if bvh is not None else build_bvh(scene)
        data = scene.segments if scene.n_segments else np.zeros((1, 20), np.float32)
        # the proxies' vertex buffer holds the segments in their draw order (nearest first: _sort_proxies),
        # "segment index" each one's index in the scene
        self._buffers = {"segments": self.ctx.buffer(np.ascontiguousarray(data, np.float32).tobytes()),
                         "segment index": self.ctx.buffer(np.arange(len(data), dtype=np.int32).tobytes())}
        if scene.guide_colors is not None:      # the groom file's colours, two vec4 per guide
            self._buffers["guide_colors"] = self.ctx.buffer(scene.guide_color_rows().tobytes())
        # the walk's copies (the proxies draw the segments from the vertex buffer above)
        self._words = {"nodes": word_image(self.ctx, self.bvh.records.reshape(-1, 4)),
                       "order": word_image(self.ctx, np.maximum(self.bvh.order, 0).astype(np.uint32)[:, None]),
                       "segments": word_image(self.ctx, np.asarray(data, np.float32).reshape(-1, 4))}

    @property
    def scene_gpu_bytes(self) -> int:
        """Bytes of GPU buffers and images that hold the scene: container segments plus their hierarchy."""
        words = sum(t.width * t.height * t.components * 4 for t in self._words.values())
        return sum(b.size for b in self._buffers.values()) + self._quad.size + words

    def frame_gpu_bytes(self, size: tuple[int, int]) -> int:
        """Bytes of the per-pixel targets of a frame at ``size`` (colour, ids, geometry, walk state): sized
        by the image, never by the scene or the fiber count."""
        return frame_gpu_bytes(size)

    def render_quality(self, p: Params, cam: Camera, size: tuple[int, int], *, outputs=("color",),
                       mode: str | None = None) -> Frame:
        """Render honouring quality.render_scale too: cast fewer rays and scale the picture up."""
        scale = p["quality.render_scale"]
        inner = (max(1, round(size[0] * scale)), max(1, round(size[1] * scale)))
        frame = self.render(p, cam, inner, outputs=outputs, mode=mode)
        if inner != tuple(size):
            frame = _upscale(frame, size)
        return frame

    # --- targets -----------------------------------------------------------------------------------
    def _target(self, size: tuple[int, int], kind: str) -> moderngl.Framebuffer:
        """The framebuffers of a frame at ``size``, all sharing one depth buffer (the mask of pixels still
        walking, renderer.render): "image" (colour RGBA8, ids RGBA32UI, geometry RGBA32F), "walk" (depth
        only) and "state" (the walk's per-pixel images: state, hit key, hit shape, cost, walk counters,
        bound as images and cleared through this framebuffer)."""
        key = (size, kind)
        if key not in self._targets:
            depth = self._targets.get((size, "depth"))
            if depth is None:
                depth = self._targets[(size, "depth")] = self.ctx.depth_renderbuffer(size)
            tex = self.ctx.texture
            if kind == "image":
                colors = [tex(size, 4, dtype=self.COLOR_DTYPE), tex(size, 4, dtype="u4"), tex(size, 4, dtype="f4")]
                self._targets[(size, "image colors")] = self.ctx.framebuffer(colors)   # cleared without depth
                self._targets[key] = self.ctx.framebuffer(colors, depth)
                self._targets[key].depth_mask = False     # the resolve reads the mask, never writes it
            elif kind == "walk":
                self._targets[key] = self.ctx.framebuffer([], depth)
            elif kind == "lists":       # the pixels still walking, two lists (walk.frag: uListIn, uListOut)
                self._targets[key] = self.ctx.framebuffer([tex(size, c, dtype=d) for c, d in LIST_IMAGES])
            elif kind == "nearest hit":     # container.frag: uNearestHit
                self._targets[key] = self.ctx.framebuffer([tex(size, 1, dtype="u4")])
            elif kind == "proxy cost":
                self._targets[key] = self.ctx.framebuffer([tex(size, 4, dtype="f4")])
            else:
                images = [tex(size, c, dtype=d) for c, d in STATE_IMAGES]
                self._targets[key] = self.ctx.framebuffer(images)
                # what each pass clears: the walk state and the filtered mode's colour always; the cost
                # counters for the cost output (the hit images are written wherever the state says there
                # is a hit)
                self._targets[(size, "state clear")] = self.ctx.framebuffer([images[0], images[5]])
                self._targets[(size, "cost clear")] = self.ctx.framebuffer(images[3:])
        return self._targets[key]

    def targets(self, size: tuple[int, int]) -> moderngl.Framebuffer:
        """The framebuffer ``render`` draws into at ``size``: colour (premultiplied RGBA8), ids (RGBA32UI),
        geometry (RGBA32F) and depth. The viewer displays its colour texture without a read-back."""
        return self._target((int(size[0]), int(size[1])), "image")

    def _msaa_samples(self, p: Params) -> int:
        n = p["quality.msaa"]
        if n == 0:
            return 0
        if n not in MSAA_PATTERNS:
            raise ParamError(f"quality.msaa = {n} is not allowed: use 0, 2, 4 or 8", key="quality.msaa")
        if n > self.ctx.max_samples:
            raise ParamError(f"quality.msaa = {n}: this OpenGL ({self.ctx.info['GL_RENDERER']}) supports at most "
                             f"{self.ctx.max_samples} samples", key="quality.msaa")
        return n

    def prepare_state(self) -> None:
        """GL state of the container draws: no blending, no culling (a proxy rectangle faces either way)."""
        self.ctx.disable(moderngl.BLEND | moderngl.CULL_FACE)

    def release_targets(self) -> None:
        release_framebuffers(self._parking, self._targets)
        self._sampled.clear()

    # --- drawing -----------------------------------------------------------------------------------
    def proxy_program(self, p: Params, mode: str, cost: bool) -> moderngl.Program:
        """The proxies strategy's program: one traversal per proxy fragment (stages/container.frag)."""
        return self.programs.get(self.ctx, "stages/container.vert", "stages/container.frag",
                                 model_defines(p, mode, cost))

    def compile_programs(self, p: Params, mode: str, cost: bool = False, antialias: bool = False) -> None:
        """Compile what a frame of ``p`` in ``mode`` may draw with, under either visibility: before a
        frame is split into strips, and to check a shader reload. Raises ShaderError (ParamError for an
        MSAA sample count this OpenGL lacks). Antialiasing draws single-ray frames: no program of its own."""
        if antialias and mode != "brute":
            self._msaa_samples(p)
        self.proxy_program(p, mode, cost)
        self.program(p, mode, cost)
        if not cost:
            self.program(p, mode, False, stage="resolve")
        self.programs.get(self.ctx, "stages/coverage.vert", "stages/coverage.frag", {})
        self.programs.get(self.ctx, "stages/fullscreen_depth.vert", "stages/mark_shown.frag",
                          {"FILTER": int(filtered(p, mode))})

    def program(self, p: Params, mode: str, cost: bool, stage: str = "walk") -> moderngl.Program:
        """The walk strategy's pass (``stage`` "walk") or the shading of its winners ("resolve")."""
        defines = {**model_defines(p, mode, cost), "WALK_CAP": WALK_CAP}
        return self.programs.get(self.ctx, "stages/fullscreen_depth.vert", f"stages/{stage}.frag", defines)

    def _set_uniforms(self, prog: moderngl.Program, p: Params, cam: Camera, size, offset) -> None:
        lay = fibers.ring_layout(p)
        sh = fibers.Shape.from_params(p)
        K = lay.rings
        w, h = size
        right, up, forward = cam.basis()
        th = math.tan(math.radians(cam.fov) / 2)
        values = {
            "uRings": K, "uFiberRadius": lay.fiber_radius, "uLengthJitter": lay.length_jitter,
            "uSeed": lay.seed, "uViewport": (w, h), "uPixelOffset": tuple(offset),
            "uNear": cam.near, "uFar": cam.far, "uDepthScale": 1.0 / math.log2(cam.far / cam.near),
            "uCamRight": tuple(right * th * w / h), "uCamUp": tuple(up * th), "uCamForward": tuple(forward),
            "uSceneFromCamera": tuple(self.scene.origin - cam.position),
            "uLightDir": tuple(light_direction(p)), "uLightIntensity": p["look.light_intensity"],
            "uAmbient": p["look.ambient"], "uBaseColor": look.base_color(p), "uRoughness": p["look.roughness"],
            "uTipColor": look.tip_color(p), "uTipBlend": p["look.tip_blend"], "uTipStart": p["look.tip_start"],
            "uGuideColors": int(p["look.color_source"] == "file" and self.scene.guide_colors is not None),
            "uExposureScale": 2.0 ** p["look.exposure"],
            "uFiberDensity": look.fiber_density(p, lay.fibers_per_container),
            "uTintVariation": p["look.tint_variation"], "uRoughnessVariation": p["look.roughness_variation"],
            "uShadowDensity": p["look.shadow_density"],
            "uEllipsoid": p["shape.ellipsoid"], "uTwist": p["shape.twist"],
            "uTwistPattern": TWIST_PATTERNS[p["shape.twist_pattern"]],
            "uCurlAmplitude": sh.curl_amplitude, "uCurlFrequency": p["shape.curl_frequency"],
            "uCurlPattern": CURL_PATTERNS[p["shape.curl_pattern"]],
            "uTipWidth": p["strand.tip_width"], "uTaperStart": p["strand.taper_start"],
            "uFrizz": sh.frizz, "uFrizzAmplitude": sh.frizz_amplitude, "uNoiseAmplitude": sh.noise_amplitude,
            "uNoiseFrequency": sh.noise_frequency,
            # the filtered mode's tent footprint: half-width quality.filter_width pixels, per unit distance;
            # a tile's camera shortens up by the tile's share of the view, so |up| keeps the view's pixel
            "uFootprint": p["quality.filter_width"] * 2.0 * th * float(np.linalg.norm(up)) / h,
        }
        for name, value in values.items():
            if name in prog:
                prog[name].value = value
        look.apply_lighting(prog, p, cam.position, cam.target)
        for name, arr in ring_uniforms(lay).items():
            if name in prog:
                prog[name].write(arr.tobytes())
        if "uClipFromCamera" in prog:
            prog["uClipFromCamera"].write(cam.clip_from_camera(w / h).T.astype(np.float32).copy().tobytes())
        self._set_bvh_uniforms(prog)

    def _set_bvh_uniforms(self, prog: moderngl.Program) -> None:
        bvh = self.bvh
        for name, value in (("uBvhLeaves", bvh.leaves), ("uBvhDepth", bvh.depth),
                            ("uSegmentCount", self.scene.n_segments)):
            if name in prog:
                prog[name].value = value
        for name, value in (("uDopBaseA", bvh.dop_base[:4]), ("uDopBaseB", bvh.dop_base[4:]),
                            ("uDopStepA", bvh.dop_step[:4]), ("uDopStepB", bvh.dop_step[4:])):
            if name in prog:
                prog[name].value = tuple(float(v) for v in value)

    def _vao(self, prog: moderngl.Program) -> moderngl.VertexArray:
        """The fullscreen triangle (no vertex buffer: fullscreen.vert places it from gl_VertexID)."""
        if (id(prog), "fullscreen") not in self._vaos:
            self._vaos[(id(prog), "fullscreen")] = self.ctx.vertex_array(prog, [])
        return self._vaos[(id(prog), "fullscreen")]

    def _proxy_vao(self, prog: moderngl.Program) -> moderngl.VertexArray:
        """Every container segment as an instance of the proxy rectangle (container.vert)."""
        key = (id(prog), "proxies")
        if key not in self._vaos:
            self._vaos[key] = self.ctx.vertex_array(prog, [
                (self._quad, "2f", "in_quad"),
                (self._buffers["segments"], "4f 4f 4f 4f 4f/i", "in_a", "in_b", "in_c", "in_d", "in_e"),
            ] + ([(self._buffers["segment index"], "i/i", "in_segment")] if "in_segment" in prog else []))
        return self._vaos[key]

    def visibility(self, p: Params, cam: Camera, size: tuple[int, int], mode: str | None = None) -> str:
        """Which way this frame finds each pixel's containers: quality.visibility, or for "auto" the walk
        once the proxies would stack WALK_LAYERS deep (proxy_layers, cached per camera and size). The
        filtered mode always walks: compositing a footprint over several containers needs each pixel's
        containers front to back with state kept between them, which the walk has and the proxies (one
        fragment per pixel kept by the depth test) have not."""
        if filtered(p, mode or p["quality.mode"]) or p["quality.visibility"] != "auto":
            return choose_visibility(p, mode, math.nan)
        key = (tuple(cam.position), tuple(cam.target), cam.fov, cam.near, tuple(size))
        if self._layers is None or self._layers[0] != key:
            self._layers = (key, proxy_layers(self.scene, cam, size))
        return choose_visibility(p, mode, self._layers[1])

    def _use(self, fbo: moderngl.Framebuffer, region: tuple[int, int, int, int]) -> None:
        """Bind ``fbo`` with the pass's viewport and scissor. moderngl keeps both per framebuffer and sets
        them on the framebuffer bound at the time, so each one is set after its own use()."""
        fbo.use()
        self.ctx.viewport = (0, 0) + tuple(fbo.size)
        self.ctx.scissor = region

    def _bind_scene(self) -> None:
        for name, unit in (("nodes", NODE_UNIT), ("order", ORDER_UNIT), ("segments", SEGMENT_UNIT)):
            self._words[name].bind_to_image(unit, read=True, write=False)
        self._progress.bind_to_storage_buffer(3)
        self._bind_guide_colors()

    def _bind_guide_colors(self) -> None:
        # without file colours the shader never reads binding 4 (uGuideColors = 0); something valid is bound
        self._buffers.get("guide_colors", self._buffers["segments"]).bind_to_storage_buffer(4)

    def _coverage(self, p: Params, cam: Camera, size) -> None:
        """Depth 0 where some node box of a coarse level of the hierarchy projects (coverage.vert), 1
        elsewhere: the walk passes run only where this drew."""
        ctx = self.ctx
        ctx.depth_func = "1"
        prog = self.programs.get(ctx, "stages/coverage.vert", "stages/coverage.frag", {})
        level = min(self.bvh.depth, COVERAGE_LEVEL)
        prog["uCoverageFirst"].value = (1 << level) - 1
        if "uGrowPx" in prog:
            prog["uGrowPx"].value = p["quality.filter_width"] if filtered(p, p["quality.mode"]) else 0.0
        self._set_bvh_uniforms(prog)
        prog["uViewport"].value = tuple(size)
        prog["uSceneFromCamera"].value = tuple(self.scene.origin - cam.position)
        prog["uClipFromCamera"].write(cam.clip_from_camera(size[0] / size[1]).T.astype(np.float32).copy().tobytes())
        self._vao(prog).render(moderngl.TRIANGLES, vertices=6, instances=1 << level)

    def _walk_draws(self, prog: moderngl.Program, p: Params, cam: Camera, size, mode: str,
                    region: tuple[int, int, int, int]) -> tuple[int, int]:
        """Walk until every covered pixel has its nearest fiber: per fiber range of ``draw_ranges`` (one
        unless a layout could pass llvmpipe's loop budget), draws of the walk pass while it reports pixels
        that need more containers than one draw walks. The first draw of a range runs over the pixels the
        coverage pass marked; each later one over the list of pixels the draw before left unfinished
        (walk.frag: uListed), packed into a rectangle at the target's corner. Returns (draws, pixels still
        unfinished after MAX_DRAWS draws of a range: 0 unless something is broken)."""
        ctx = self.ctx
        vao = self._vao(prog)
        traversals = traversals_per_fragment(p, mode)
        ranges = draw_ranges(p, self.scene, mode, traversals, walks=2)
        if "uRingOrder" in prog:
            prog["uRingOrder"].value = int(len(ranges) > 1 or needs_ring_order(p, self.scene, mode, traversals,
                                                                               walks=2))
        prog["uDepth"].value = WALK_DEPTH
        walk = self._target(size, "walk")
        lists = self._target(size, "lists").color_attachments
        # the pixels a range starts on: depth 0 where a coarse level of the hierarchy projects
        walk.depth_mask = True
        self._use(walk, region)
        walk.clear(depth=1.0)
        self._coverage(p, cam, size)
        walk.depth_mask = False         # early tests: a write in the walk would land before the shader ran
        draws, left = 0, 0
        zero = bytes(4)
        for start, end in ranges:
            for name in ("uBruteRange", "uFiberRange"):
                if name in prog:
                    prog[name].value = (start, end)
            if "uCoverOn" in prog:          # the coverage scan tests whole rings: once, in the first range
                prog["uCoverOn"].value = int(start == 0)
            for k in range(MAX_DRAWS):
                # draw k walks the list draw k - 1 appended to and appends to the other one
                lists[k % 2].bind_to_image(LIST_UNITS[0], read=True, write=False)
                lists[(k + 1) % 2].bind_to_image(LIST_UNITS[1], read=False, write=True)
                prog["uRestart"].value = int(k == 0)
                prog["uListed"].value = int(k > 0)
                self._progress.write(zero)
                if k == 0:
                    ctx.enable(moderngl.DEPTH_TEST)
                    ctx.depth_func = ">"
                    self._use(walk, region)
                else:
                    width, height, blocks = list_rectangle(left, size)
                    prog["uListCount"].value = left
                    prog["uListWidth"].value = width
                    prog["uListBlocks"].value = blocks
                    ctx.disable(moderngl.DEPTH_TEST)
                    self._use(walk, (0, 0, width, height))
                vao.render(moderngl.TRIANGLES, vertices=3)
                draws += 1
                ctx.memory_barrier()            # the image stores land before the next draw reads them
                left = int(np.frombuffer(self._progress.read(), np.uint32)[0])
                if left == 0:
                    break
        ctx.enable(moderngl.DEPTH_TEST)         # the resolve keeps to the coverage pass's pixels
        return draws, left

    def _pass(self, p: Params, cam: Camera, size, offset, mode: str, cost: bool,
              region: tuple[int, int, int, int]) -> tuple[int, int]:
        """One sample of the frame: the walk (state images), then, for the picture, the shading of each
        pixel's winner into the "image" targets. Only ``region`` is cleared and drawn."""
        ctx = self.ctx
        state = self._target(size, "state")
        used = [self._targets[(size, name)] for name in (("state clear", "cost clear") if cost else ("state clear",))]
        for fbo in used:
            self._use(fbo, region)
            fbo.clear(0.0, 0.0, 0.0, 0.0)     # state all zero: a fresh pixel
        for unit, tex in enumerate(state.color_attachments):
            tex.bind_to_image(unit, read=True, write=True)
        self._bind_scene()
        ctx.enable(moderngl.DEPTH_TEST)
        walk = self._target(size, "walk")
        used.append(walk)
        self._use(walk, region)
        prog = self.program(p, mode, cost=cost)
        self._set_uniforms(prog, p, cam, size, offset)
        draws, left = self._walk_draws(prog, p, cam, size, mode, region)
        ctx.memory_barrier()
        if not cost:
            # pixels the walk ran on that show nothing get EMPTY_DEPTH, past the resolve's (mark_shown.frag)
            mark = self.programs.get(ctx, "stages/fullscreen_depth.vert", "stages/mark_shown.frag",
                                     {"FILTER": int(filtered(p, mode))})
            mark["uDepth"].value = EMPTY_DEPTH
            walk.depth_mask = True
            self._use(walk, region)
            ctx.depth_func = ">"
            self._vao(mark).render(moderngl.TRIANGLES, vertices=3)
            walk.depth_mask = False
            fbo = self._target(size, "image")
            self._use(self._targets[(size, "image colors")], region)
            clear_targets(self._targets[(size, "image colors")])
            used += [self._targets[(size, "image colors")], fbo]
            self._use(fbo, region)
            ctx.depth_func = ">"                    # where a pixel shows something: RESOLVE_DEPTH > 0
            resolve = self.program(p, mode, cost=False, stage="resolve")
            self._set_uniforms(resolve, p, cam, size, offset)
            resolve["uDepth"].value = RESOLVE_DEPTH
            self._vao(resolve).render(moderngl.TRIANGLES, vertices=3)
            draws += 1
        ctx.disable(moderngl.DEPTH_TEST)
        for fbo in used:                            # leave no scissor behind on a target others read or clear
            fbo.scissor = None
        return draws, left

    # --- the proxies strategy ------------------------------------------------------------------------
    def _sort_proxies(self, cam: Camera) -> None:
        """Put the proxies in the order they are drawn: nearest segment midpoint first, so the fragments at
        a pixel mostly come front to back and each traversal after the first is cut at the hit before it
        (container.frag: nearest_so_far). Any order gives the same picture; this one does the least work.
        Sorted again only when the camera moves."""
        if self._proxy_order_from == tuple(cam.position) or self.scene.n_segments < 2:
            return
        self._proxy_order_from = tuple(cam.position)
        seg = self.scene.segments
        mid = 0.5 * (seg[:, 0:3].astype(np.float64) + seg[:, 4:7]) + (self.scene.origin - cam.position)
        order = np.argsort(np.einsum("ij,ij->i", mid, mid), kind="stable")
        self._buffers["segments"].write(np.ascontiguousarray(seg[order], np.float32).tobytes())
        self._buffers["segment index"].write(order.astype(np.int32).tobytes())

    def _proxy_draws(self, prog: moderngl.Program, p: Params, cam: Camera, fbo: moderngl.Framebuffer, region,
                     mode: str, rays: int) -> int:
        """Draw every container's proxy once per range of ``draw_ranges``, nearest first; the depth test keeps
        the nearest hit across containers and ranges, and each pixel's nearest hit so far (cleared here)
        lets a later fragment stop there. Returns the draw count."""
        self._sort_proxies(cam)
        nearest = self._target(tuple(fbo.size), "nearest hit")
        nearest.clear(0.0, 0.0, 0.0, 0.0)
        nearest.color_attachments[0].bind_to_image(NEAREST_UNIT, read=True, write=True)
        self._use(fbo, region)              # back to the pass's framebuffer (creating one binds it)
        vao = self._proxy_vao(prog)
        self._bind_guide_colors()
        ranges = draw_ranges(p, self.scene, mode, rays)
        if "uRingOrder" in prog:
            prog["uRingOrder"].value = int(len(ranges) > 1 or needs_ring_order(p, self.scene, mode, rays))
        for start, end in ranges:
            for name in ("uBruteRange", "uFiberRange"):
                if name in prog:
                    prog[name].value = (start, end)
            vao.render(moderngl.TRIANGLES, instances=self.scene.n_segments)
        return len(ranges)

    def _proxy_pass(self, p: Params, cam: Camera, size, offset, mode: str, region) -> int:
        """One single-ray sample of the frame by the proxies strategy: every container segment drawn as its
        screen rectangle, one traversal per fragment, the depth test keeping the nearest (stages/
        container.vert, container.frag), into the "image" targets. Antialiasing draws one of these per
        sample (``render``): a fragment sees only its own container, so rays traced inside it could not
        reach a container behind where they miss, and the depth test keeps one fragment per pixel.
        Returns the draw count."""
        fbo = self._target(size, "image")
        fbo.depth_mask = True
        self._use(fbo, region)
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.ctx.depth_func = "<"
        clear_targets(fbo)
        prog = self.proxy_program(p, mode, cost=False)
        self._set_uniforms(prog, p, cam, size, offset)
        draws = self._proxy_draws(prog, p, cam, fbo, region, mode, traversals_per_fragment(p, mode))
        fbo.depth_mask = False
        self.ctx.disable(moderngl.DEPTH_TEST)
        fbo.scissor = None
        return draws

    def _proxy_cost(self, p: Params, cam: Camera, size, outputs, offset, mode: str, region, frame: Frame) -> None:
        """The proxies' cost and iters outputs: the work of every proxy fragment, added up (or the most of
        it, for iters) by blending."""
        ctx = self.ctx
        rays = traversals_per_fragment(p, mode)
        for kind in ("cost", "iters"):
            if kind not in outputs:
                continue
            fbo = self._target(size, "proxy cost")
            self._use(fbo, region)
            fbo.clear(0.0, 0.0, 0.0, 0.0)
            ctx.enable(moderngl.BLEND)
            ctx.blend_func = moderngl.ONE, moderngl.ONE
            ctx.blend_equation = moderngl.FUNC_ADD if kind == "cost" else moderngl.MAX
            prog = self.proxy_program(p, mode, cost=True)
            self._set_uniforms(prog, p, cam, size, offset)
            frame.draws += self._proxy_draws(prog, p, cam, fbo, region, mode, rays)
            data = _read(fbo, 0, 4, "f4", size)
            if kind == "cost":
                # every proxy fragment the ray entered traversed its container; no hierarchy was walked
                frame.cost = data
                frame.walk = np.zeros_like(data)
                frame.walk[..., 0] = data[..., 2]
            else:
                frame.iters = data[..., 3]
            ctx.blend_equation = moderngl.FUNC_ADD
            ctx.disable(moderngl.BLEND)
            fbo.scissor = None

    def _keep_outside(self, size, region, *images):
        """A frame of several samples is a mean of read-backs, which no target holds, so the renderer keeps
        the last one per size (premultiplied colour, ids, geometry; None: not asked for): outside ``region``
        an antialiased frame drawn in tiles shows what earlier calls drew, as a one-ray frame's targets do."""
        last = self._sampled.get(size, (None,) * len(images))
        if region != (0, 0) + size:
            x, y, w, h = region
            inside = np.zeros((size[1], size[0], 1), bool)
            inside[size[1] - y - h:size[1] - y, x:x + w] = True      # read-backs are top row first
            images = tuple(new if new is None or old is None else np.where(inside, new, old)
                           for new, old in zip(images, last))
        self._sampled[size] = tuple(new if new is not None else old for new, old in zip(images, last))
        return images

    # --- a frame -----------------------------------------------------------------------------------------
    def render(self, p: Params, cam: Camera, size: tuple[int, int], *, outputs=("color",),
               offset=(0.0, 0.0), mode: str | None = None, antialias: bool = True,
               region: tuple[int, int, int, int] | None = None) -> Frame:
        """Render the scene. ``outputs`` is any of color, ids, geom, cost, iters, draw (no read-back).

        Both ways of finding a pixel's containers (``visibility``) give every output and the same fibers.
        With ``antialias``, colour honours quality.supersample (n x n stratified rays per pixel) or
        quality.msaa (one ray at each of the standard sample positions, MSAA_PATTERNS); brute force always
        casts one ray per pixel: it is the reference for ids. Either strategy casts a whole single-ray frame
        per sample, averages the premultiplied colours and takes the nearest sample's ids, normal and depth,
        so both give the same picture in every mode. ``region`` (x, y, w, h in
        pixels, GL's bottom-left origin) renders only that rectangle: the rest of the targets keeps what
        earlier calls drew (tiled refinement).
        """
        if self.scene is None:
            raise RuntimeError("Renderer.render: call set_scene first")
        mode = mode or p["quality.mode"]
        size = (int(size[0]), int(size[1]))
        region = (0, 0) + size if region is None else tuple(int(v) for v in region)
        self.prepare_state()
        proxies = self.visibility(p, cam, size, mode) == "proxies"
        frame = Frame()
        offsets = [tuple(offset)]
        if antialias and mode != "brute":
            n, msaa = p["quality.supersample"], self._msaa_samples(p)
            if msaa:
                offsets = [(offset[0] + x / 16.0, offset[1] + y / 16.0) for x, y in MSAA_PATTERNS[msaa]]
            elif n > 1:
                offsets = [(offset[0] + x, offset[1] + y) for x, y in supersample_offsets(n)]
        image_outputs = {"color", "ids", "geom", "draw"} & set(outputs)
        if image_outputs:
            rgba, ids, geom = None, None, None
            fbo = self._target(size, "image")
            for o in offsets:
                if proxies:
                    draws, left = self._proxy_pass(p, cam, size, o, mode, region), 0
                else:
                    draws, left = self._pass(p, cam, size, o, mode, False, region)
                frame.draws += draws
                frame.unfinished = max(frame.unfinished, left)
                if len(offsets) == 1 and not ({"color", "ids", "geom"} & image_outputs):
                    break                               # "draw": the targets hold the frame
                if "color" in outputs:
                    sample = _read(fbo, 0, 4, "f1", size)
                    if len(offsets) > 1:
                        sample = sample.astype(np.float64)      # a sum of samples outgrows uint8
                    rgba = sample if rgba is None else rgba + sample
                if {"ids", "geom"} & image_outputs:
                    s_ids, s_geom = _read(fbo, 1, 4, "u4", size), _read(fbo, 2, 4, "f4", size)
                    if ids is None:
                        ids, geom = s_ids, s_geom
                    else:                               # the nearest hit over the samples names the pixel
                        nearer = (s_ids[..., 0] > 0) & ((ids[..., 0] == 0) | (s_geom[..., 3] < geom[..., 3]))
                        ids[nearer], geom[nearer] = s_ids[nearer], s_geom[nearer]
            if len(offsets) > 1:
                rgba, ids, geom = self._keep_outside(size, region, rgba / len(offsets) if rgba is not None
                                                     else None, ids, geom)
            if "color" in outputs:
                frame.color, frame.coverage = _composite(rgba, p)
            if "ids" in outputs:
                frame.ids = ids
            if "geom" in outputs:
                frame.geom = geom
        if {"cost", "iters"} & set(outputs) and proxies:
            self._proxy_cost(p, cam, size, outputs, offset, mode, region, frame)
        elif {"cost", "iters"} & set(outputs):
            draws, left = self._pass(p, cam, size, offsets[0], mode, True, region)
            frame.draws += draws
            state = self._target(size, "state")
            cost, walk = _read(state, 3, 4, "f4", size), _read(state, 4, 4, "f4", size)
            if "cost" in outputs:
                frame.cost, frame.walk = cost, walk
            if "iters" in outputs:
                frame.iters = walk[..., 3]
        return frame


EPS_ANGLE = 2e-5                        # glsl/common/epsilon.glsl
EPS_TURNED_CHORD = 0.08                 # glsl/common/epsilon.glsl: a turned window's slack


def ring_uniforms(lay: fibers.RingLayout) -> dict[str, np.ndarray]:
    """The per-ring uniform arrays of glsl/fibers/layout.glsl, padded to MAX_RINGS. Besides the layout,
    uRingB carries what the traversal would otherwise divide for per arc: 1 / dphi, and how many
    candidates past an improvement can still be nearer (2 reaches, fibers/straight.glsl)."""
    K = lay.rings
    ring_a = np.zeros((MAX_RINGS, 4), np.float32)
    ring_b = np.zeros((MAX_RINGS, 4), np.float32)
    ring_n = np.zeros((MAX_RINGS, 2), np.int32)
    ring_a[:K] = np.stack([lay.rho, lay.dphi, lay.rot, lay.reach], 1)
    after = np.floor(2.0 * (lay.reach + EPS_ANGLE) / lay.dphi * (1.0 + 1e-6)) + 1.0
    ring_b[:K] = np.stack([lay.max_dr, lay.max_dphi, 1.0 / lay.dphi, after], 1)
    ring_n[:K, 0], ring_n[:K, 1] = lay.n, lay.first
    ring_radius = np.zeros(MAX_RINGS, np.float32)
    ring_radius[:K] = lay.ring_radius            # the clump profile's fiber radius by ring
    return {"uRingA": ring_a, "uRingB": ring_b, "uRingN": ring_n, "uRingRadius": ring_radius}


def traversals_per_fragment(p: Params, mode: str) -> int:
    """Traversals per container one ray can run: one, two with traced shadows (each hit sends a shadow ray
    through the same container). Antialiasing draws each sample's ray in a pass of its own."""
    return 2 if p["look.self_shadow"] == "traced" else 1


# Loop passes one traversal may spend in fast and exact modes, per draw: what the budget leaves once the
# shading, the loop canary and rounding in the bound below are paid for.
LOOP_HEADROOM = 1024


def candidate_caps(p: Params, scene: Scene) -> tuple[np.ndarray, int]:
    """Per ring, the most fibers one piece (arc) of a ray can test in fast and exact modes, and the loop
    passes one test costs. Mirrors the candidate windows of glsl/fibers/straight.glsl and candidates.glsl: a
    piece of ring i runs between the ring's outer circle and its inner circle or the ray's closest approach to the axis;
    seen from the axis it sweeps at most acos(inner / outer). The window adds the ring's reach on either
    side. Curved fibers: per ring the loop passes of one arc, all its chord pieces included, and 1
    (``_shaped_arc_passes``)."""
    lay = fibers.ring_layout(p)
    eps_angle = EPS_ANGLE
    K = lay.rings
    if not is_shaped(p):
        inner, outer = 1.0 - (np.arange(K) + 1.0) / K, 1.0 - np.arange(K) / K
        widen = 2.0 * (lay.reach + eps_angle)
        per_test = 1
    else:
        return _shaped_arc_passes(p, scene), 1
    closest = np.minimum.accumulate(inner)              # no ring deeper than the ray's closest approach
    sweep = np.arccos(np.clip(closest / outer, 0.0, 1.0)) + 1e-3
    caps = np.minimum(lay.n, np.floor((sweep + widen) / lay.dphi).astype(np.int64) + 2)
    return caps, per_test


def _shaped_arc_passes(p: Params, scene: Scene) -> np.ndarray:
    """Curved fibers (glsl/fibers/shaped.glsl): per ring, the most loop passes one visit of an arc takes,
    all of the ring's fibers in the draw. The arc is cut into at most MAX_SUB chord pieces; a piece tests
    the slots within the ring's reach of the angles its ray sweeps less the twist's range over the piece
    (shaped.glsl: piece_window; its turning frame's window is at most 2 EPS_TURNED_CHORD wider). Seen from
    the axis an arc of the ray sweeps at most acos(inner / outer), so all pieces together sweep at most that
    plus the twist over the segment, and each piece adds its two reaches. A piece turns at most
    sqrt(0.8 r_f / rho) with the twist (the chord rule, curved.glsl), or a MAX_SUB-th of the segment's
    twist where the rule is capped, and its rest chords dip toward the axis by cos(turn / 2) (the reach's
    disc); a window that spans more than 2.5 radians takes every fiber of the ring."""
    lay = fibers.ring_layout(p)
    sh = fibers.Shape.from_params(p)
    seg = scene.segments.astype(np.float64)
    axis = seg[:, 4:7] - seg[:, 0:3]
    h = np.linalg.norm(axis, axis=1)
    ez = axis / h[:, None]

    r_bound = np.maximum(seg[:, 3], seg[:, 7])
    z_lo = -r_bound * joint_slope((seg[:, 8:11] * ez).sum(1))
    z_hi = h + r_bound * joint_slope((seg[:, 12:15] * ez).sum(1))
    v_lo = seg[:, 11] + (seg[:, 15] - seg[:, 11]) * z_lo / h   # the guide parameter over the slab
    v_hi = seg[:, 11] + (seg[:, 15] - seg[:, 11]) * z_hi / h
    e_lo = float(np.min(np.minimum(fibers.shape_scale(sh, v_lo), fibers.shape_scale(sh, v_hi))))
    grow = lay.fiber_radius + sh.displacement + 1e-6      # shaped.glsl: ring_band
    inner = np.maximum(0.0, e_lo * (lay.rho - lay.max_dr) - grow)
    outer = (lay.rho + lay.max_dr) + grow                   # e_hi <= 1
    closest = np.minimum.accumulate(inner)              # no ring deeper than the ray's closest approach
    sweep = np.arccos(np.clip(closest / outer, 0.0, 1.0)) + 1e-3
    ramped = sh.twist_pattern == fibers.TWIST_RAMPED
    dv = np.abs(v_hi - v_lo) * (2.0 * np.maximum(np.abs(v_lo), np.abs(v_hi)) if ramped else 1.0)
    twist = 2.0 * math.pi * abs(sh.twist) * float(dv.max()) * 1.001
    rho_chord = lay.rho + lay.max_dr                        # curved.glsl: chord_pieces
    piece_turn = np.minimum(twist, np.maximum(np.sqrt(0.8 * max(lay.fiber_radius, 1e-30) / rho_chord) * 1.001,
                                              twist / MAX_SUB))
    chord_cos = np.where(piece_turn < 3.0, np.cos(np.minimum(piece_turn, 3.0) / 2.0), 0.0)
    d_min = e_lo * (lay.rho - lay.max_dr) * chord_cos * (1.0 - 1e-3)   # shaped.glsl: shaped_reach
    r = lay.fiber_radius + sh.displacement
    with np.errstate(divide="ignore", invalid="ignore"):
        disc = np.where(d_min > r, np.arcsin(np.minimum(1.0, r / d_min)), math.pi)
    reach = lay.max_dphi + disc + EPS_ANGLE
    per_piece = np.floor(2.0 * (reach + EPS_TURNED_CHORD) / lay.dphi).astype(np.int64) + 2
    swept = np.floor((sweep + twist) / lay.dphi).astype(np.int64) + MAX_SUB * per_piece
    whole = sweep + piece_turn > 2.5 - 1e-3                 # shaped.glsl: the near-axis chord takes all
    tests = np.where(whole, MAX_SUB * lay.n, np.minimum(MAX_SUB * lay.n, swept))
    return _shaped_visit_passes(tests, screened(p))


def screened(p: Params) -> bool:
    """Whether the shaped traversal screens a piece's candidates by length (glsl/fibers/shaped.glsl:
    SHAPED_SCREEN, built in with curl, frizz or noise)."""
    return shape_curl_define(p) != 0 or is_frizzed(p)


def _shaped_visit_passes(tests, screen: bool):
    """Loop passes of one visit of a curved ring's arc that tests at most ``tests`` candidates over its
    MAX_SUB chord pieces, each piece paying its header and its scan's final test. Screened, a piece's window
    goes in chunks of 32 candidates, each screened then tested (two passes a candidate) and paying three
    headers (its own, the screen's and the tests' final one); the pieces have at most tests // 32 + MAX_SUB
    chunks in all."""
    if not screen:
        return tests + 2 * MAX_SUB + 1
    return 2 * tests + 3 * (tests // 32 + MAX_SUB) + 2 * MAX_SUB + 1


def _loop_budget(p: Params, rays: int, walks: int = 0) -> int:
    """Loop passes one traversal may spend in one draw: the budget less the shading's share, the walks
    through the hierarchy (WALK_CAP box tests each, raycast.frag), the filtered mode's coverage scan (at
    most COVER_CAP candidates per ring visit) and the ring, arc and canary loops."""
    # the scan's ring visits and candidates, the medium's rings, their light nodes and two arcs
    K = p["fibers.rings"]
    cover = 2 * K * (COVER_CAP + 2) + 1 + K * (COVER_LIGHT_NODES + 3) + 1 if p["quality.filter"] != "off" else 0
    return ((LOOP_CAP - LOOP_HEADROOM - walks * (WALK_CAP + 1) - cover) // max(1, rays)
            - (16 * p["fibers.rings"] + 16))


def needs_ring_order(p: Params, scene: Scene, mode: str, rays: int = 1, walks: int = 0) -> bool:
    """Whether one draw of every fiber needs the traversal's loops after the ring loop to go by ring index
    (uRingOrder). Each lane's own order is cheaper, but then lanes of a batch can visit different rings at
    one iteration, and the batch pays the costliest of them. Straight: fronts and first halves by ring,
    plus up to K times the costliest ring for the loops after. Curved (glsl/fibers/shaped.glsl): a lane's
    arcs go in by ring and come back out, so at pass p every lane is on a ring no deeper than
    min(p, 2K - 1 - p) and the batch pays at most the costliest ring up to there: twice the sum of the
    running maximum of the rings' costs."""
    if mode == "brute":
        return False
    caps, per_test = candidate_caps(p, scene)
    tests = per_test * caps
    if not is_shaped(p):
        worst = tests.sum() + (p["fibers.rings"] + 1) * tests.max()
    else:
        worst = 2 * np.maximum.accumulate(tests).sum()
    return bool(worst > _loop_budget(p, rays, walks))


def draw_ranges(p: Params, scene: Scene, mode: str, rays: int = 1, walks: int = 0) -> list[tuple[int, int]]:
    """Ranges [start, end) of a container's flat fiber numbering, one draw each, such that no SIMD batch of
    fragments passes llvmpipe's loop budget: it would stop every loop in silence and lose fibers.

    Brute force tests each fiber of its chunk once (straight) or on each chord piece of each arc (curved).
    Fast and exact test a ring's candidates on each piece of the ray in that ring, at most
    ``candidate_caps`` of them (curved: the loop passes of one arc, all its chord pieces included). A batch
    visits a straight ring on its front and back pieces, and the deepest pieces of its lanes (any ring, the
    costliest one bounds them); a curved ring on up to two arcs (glsl/fibers/shaped.glsl: going in, coming
    out). Rings are packed into draws greedily, a ring split when it alone is too much. Every bundled layout
    needs one draw; 64 rings of 0.01 degree fibers, or curled fibers whose reach is the whole ring, need
    several, and the depth test keeps the nearest hit across them as it does in brute mode. The bound holds
    with the loops after the ring loop (curved: the arcs) in ring order (uRingOrder), which the renderer sets
    whenever there is more than one draw or ``needs_ring_order``. ``rays``: traversals per invocation;
    ``walks``: walks through the container hierarchy per invocation (the walk strategy)."""
    lay = fibers.ring_layout(p)
    total = lay.fibers_per_container
    if mode == "brute":
        # loop passes per fiber: one (straight), up to four arcs of a chord loop each (curved)
        per_fiber = 4 * (MAX_SUB + 2) if is_shaped(p) else 1
        full = BRUTE_CHUNK_SHAPED if is_shaped(p) else BRUTE_CHUNK      # fibers for one traversal, no walk
        chunk = max(1, (full * per_fiber - walks * (WALK_CAP + 1)) // (per_fiber * max(1, rays)))
        return [(start, min(total, start + chunk)) for start in range(0, total, chunk)]
    caps, per_test = candidate_caps(p, scene)
    budget = _loop_budget(p, rays, walks)
    shaped = is_shaped(p)
    # per ring: arcs a batch may visit it on; per draw: deepest pieces, at the draw's costliest ring
    visits, deepest = (2, 2) if not shaped else (2, 0)

    screen = shaped and screened(p)

    def cost(i: int, m: int) -> int:
        """Loop passes of one visit of ring i with m of its fibers in the draw."""
        if shaped:      # every piece tests at most the share
            return min(int(caps[i]), int(_shaped_visit_passes(MAX_SUB * m, screen)))
        return per_test * min(m, int(caps[i]))

    if (visits + deepest) * cost(0, 1) > budget:
        raise ValueError(f"{rays} traversals per fragment leave no loop budget for one fiber test")
    ranges, start, used, top = [], 0, 0, 0                      # top: the open draw's costliest ring
    for i in range(lay.rings):
        pos, left = int(lay.first[i]), int(lay.n[i])
        while left > 0:
            tests = cost(i, left)
            if used + visits * tests + deepest * max(top, tests) <= budget:
                used, top, pos, left = used + visits * tests, max(top, tests), pos + left, 0
                continue
            # the fibers of this ring that still fit
            if shaped:
                fit, over = 0, left                 # the most m with visits * cost(i, m) <= budget - used
                while over - fit > 1:
                    mid = (fit + over) // 2
                    fit, over = (mid, over) if used + visits * cost(i, mid) <= budget else (fit, mid)
            else:
                fit = (budget - used - deepest * top) // ((visits + deepest) * per_test)
            if fit > 0:
                pos, left = pos + fit, left - fit
            if pos > start:
                ranges.append((start, pos))
            start, used, top = pos, 0, 0
    ranges.append((start, total))
    return ranges


def model_defines(p: Params, mode: str, cost: bool) -> dict[str, int]:
    """The defines of the fiber model and the traversal, the same for either visibility strategy."""
    return {**fibers.glsl_defines(), "TRAVERSAL": MODES[mode], "FILTER": int(filtered(p, mode)),
            "COVER_CAP": COVER_CAP, "COVER_LIGHT_NODES": COVER_LIGHT_NODES,
            "HASH_THESIS": int(p["fibers.hash"] == "thesis"), "COST_PASS": int(cost),
            "SHAPED": int(is_shaped(p)), "SHAPE_CURL": shape_curl_define(p), "SHAPE_FRIZZ": int(is_frizzed(p)),
            "SHAPE_ELLIPSOID": int(p["shape.ellipsoid"] > 0), "SHAPE_TWIST": int(p["shape.twist"] != 0),
            "SHADING_MODEL": SHADING_MODELS[p["look.model"]], "SHADOW_MODE": SHADOW_MODES[p["look.self_shadow"]],
            "TAPER": int(fibers.tapered(p))}       # glsl/fibers/taper.glsl: tip width 1 builds no cone


def filter_applies(p: Params, mode: str) -> bool:
    """Whether quality.filter can colour a frame of ``p`` in ``mode``: exact mode. Fast mode takes the first
    container with a hit, which the filter's grown bounds would reorder (its ids would change); brute force
    is the reference for ids (the viewer greys the switch and says why: vocabulary.py). Tapered tips are
    filtered too: the scan takes each fiber's width where the ray passes it, the medium their mean width
    (glsl/fibers/coverage.glsl)."""
    return mode == "exact"


def filtered(p: Params, mode: str) -> bool:
    """Whether a frame gets the filtered colour (quality.filter, glsl/fibers/coverage.glsl)."""
    return p["quality.filter"] == "coverage" and filter_applies(p, mode)


def shape_curl_define(p: Params) -> int:
    """What the shaped traversal builds in for the curl (glsl/fibers/shape.glsl): 0 none, 1 helix, 2 wave."""
    return 0 if p["shape.curl_amplitude"] <= 0 else 1 + CURL_PATTERNS[p["shape.curl_pattern"]]


def is_shaped(p: Params) -> bool:
    """Curved fibers need the slower curved-fiber traversal; straight ones keep the fast path."""
    return p["shape.ellipsoid"] > 0 or p["shape.curl_amplitude"] > 0 or p["shape.twist"] != 0 or is_frizzed(p)


def is_frizzed(p: Params) -> bool:
    """Frizz or noise on: the shaped traversal builds in their displacement (shape.glsl: SHAPE_FRIZZ)."""
    return p["shape.frizz"] > 0 or p["shape.noise"] > 0


def clear_targets(fbo: moderngl.Framebuffer) -> None:
    """Zero every colour attachment and set depth to 1. moderngl clears each attachment with the
    glClearBuffer call of its type (uiv for the integer ids, fv for the others: tests/gl/test_gl_infra.py), so
    the integer target is cleared as GL defines, where glClear would leave it undefined."""
    fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)


def release_framebuffers(parking: moderngl.Framebuffer, targets: dict) -> None:
    """Release framebuffers and their attachments. A live ``parking`` framebuffer is bound first: moderngl
    rebinds the current framebuffer whenever it creates one, and rebinding a released one is an invalid
    operation that the next test or frame would inherit."""
    parking.use()
    owned: dict[int, object] = {}           # framebuffers may share attachments: release each once
    for obj in targets.values():
        if isinstance(obj, moderngl.Framebuffer):
            for a in (*obj.color_attachments, obj.depth_attachment):
                if a is not None:
                    owned[id(a)] = a
        owned[id(obj)] = obj
    for obj in owned.values():
        if not isinstance(obj, moderngl.Framebuffer):
            continue
        obj.release()
    for obj in owned.values():
        if not isinstance(obj, moderngl.Framebuffer):
            obj.release()
    targets.clear()


def word_rows(words: int) -> int:
    """Rows of WORD_ROW texels that hold ``words`` texels (at least one)."""
    return max(1, -(-int(words) // WORD_ROW))


def word_image_size(words: int) -> tuple[int, int]:
    """The image that holds ``words`` texels: rows of WORD_ROW, or one row just as long for fewer (word k
    is at (k mod WORD_ROW, k / WORD_ROW) either way), so a small scene's images stay small."""
    return min(WORD_ROW, max(int(words), 1)), word_rows(words)


def word_image(ctx: moderngl.Context, words: np.ndarray) -> moderngl.Texture:
    """An image of ``words`` ((n, 4) float32 or (n, 1) uint32), WORD_ROW texels a row, zero past the end."""
    n, components = words.shape
    width, rows = word_image_size(n)
    if rows > ctx.info["GL_MAX_TEXTURE_SIZE"]:
        raise HierarchyTooLarge(f"{n:,} words of scene data need {word_rows(n):,} rows of {WORD_ROW} texels; this "
                                f"OpenGL's images hold {ctx.info['GL_MAX_TEXTURE_SIZE']:,} (fewer container "
                                "segments: scene.groom_cluster, or sample fewer strands)")
    padded = np.zeros((rows * width, components), words.dtype)
    padded[:n] = words
    return ctx.texture((width, rows), components, padded.tobytes(), dtype="u4" if words.dtype == np.uint32 else "f4")


def scene_gpu_bytes(scene: Scene) -> int:
    """What ``Renderer.set_scene`` allocates for ``scene``: the segments (a vertex buffer for the proxies, in
    their draw order with each one's scene index, and an image for the walk), the per-guide colours (a groom
    file's, where it has them), the hierarchy's nodes and order (images), the shared proxy rectangle."""
    n = max(scene.n_segments, 1)
    records, order = bvh_words(scene.n_segments)
    texels = [np.prod(word_image_size(words)) for words in (5 * n, records, order)]
    return (max(scene.segments.nbytes, 80) + 4 * n + scene.guide_color_bytes + _QUAD.nbytes
            + int(16 * (texels[0] + texels[1]) + 4 * texels[2]))


def choose_visibility(p: Params, mode: str | None, layers: float) -> str:
    """"walk" or "proxies" for a frame whose proxies would stack ``layers`` deep over a covered pixel
    (proxy_layers; unused unless quality.visibility is "auto" and the frame is not filtered): the one rule
    that the renderer follows and the work estimate (budget.py) predicts."""
    if filtered(p, mode or p["quality.mode"]):
        return "walk"
    choice = p["quality.visibility"]
    if choice != "auto":
        return choice
    return "walk" if layers > WALK_LAYERS else "proxies"


def proxy_layers(scene: Scene, cam: Camera, size: tuple[int, int], grid: int = 64) -> float:
    """How many container proxies stack over a covered pixel, on average: each segment's screen
    rectangle (its end points widened by its radius) counted on a coarse grid, a rectangle smaller than
    its cells counted by its share of them. The proxies strategy costs a traversal per layer; the walk
    a walk plus the containers in front of each pixel's fiber. A segment reaching behind the camera
    makes it infinite (its proxy covers the whole viewport). At most LAYER_SAMPLE segments are counted."""
    if scene.n_segments == 0:
        return 0.0
    # the viewer asks on every camera move: past LAYER_SAMPLE segments every stride-th one stands for its
    # neighbours (strands are stored root to tip, so a stride samples the whole groom)
    stride = max(1, -(-scene.n_segments // LAYER_SAMPLE))
    seg = scene.segments[::stride].astype(np.float64)
    right, up, forward = (np.asarray(v, np.float64) for v in cam.basis())
    rel = scene.origin - cam.position
    w, h = size
    th = math.tan(math.radians(cam.fov) / 2)
    aspect = w / h

    def project(q: np.ndarray):
        z = q @ forward
        return (q @ right) / (z * th * aspect), (q @ up) / (z * th), z

    x0, y0, z0 = project(seg[:, 0:3] + rel)
    x1, y1, z1 = project(seg[:, 4:7] + rel)
    z = np.minimum(z0, z1)
    if (z <= cam.near).any():
        return math.inf
    rad = np.maximum(seg[:, 3], seg[:, 7]) / z / th            # in y ndc units
    xa, xb = np.minimum(x0, x1) - rad / aspect, np.maximum(x0, x1) + rad / aspect
    ya, yb = np.minimum(y0, y1) - rad, np.maximum(y0, y1) + rad
    seen = (xb > -1) & (xa < 1) & (yb > -1) & (ya < 1)
    xa, xb, ya, yb = xa[seen], xb[seen], ya[seen], yb[seen]
    gx, gy = grid, max(1, round(grid / aspect))

    def cell(v, n):
        return np.clip(((v + 1) / 2 * n).astype(np.int64), 0, n - 1)

    cx0, cx1, cy0, cy1 = cell(xa, gx), cell(xb, gx) + 1, cell(ya, gy), cell(yb, gy) + 1
    share = stride * np.minimum(1.0, (xb - xa) * (yb - ya) / 4 * gx * gy / ((cx1 - cx0) * (cy1 - cy0)))
    diff = np.zeros((gy + 1, gx + 1))                           # a 2D difference array of the rectangles
    for yy, xx, sign in ((cy0, cx0, 1), (cy0, cx1, -1), (cy1, cx0, -1), (cy1, cx1, 1)):
        np.add.at(diff, (yy, xx), sign * share)
    counts = diff.cumsum(0).cumsum(1)[:gy, :gx]
    covered = counts > 0.05
    return float(counts[covered].mean()) if covered.any() else 0.0


# The walk's per-pixel images (Renderer._target "state"), (components, dtype): state, hit key, hit shape, the
# two cost images, the filtered mode's colour and its transmittance (always there: one program set).
STATE_IMAGES = ((4, "u4"), (4, "u4"), (4, "f4"), (4, "f4"), (4, "f4"), (4, "f4"), (1, "f4"))
# The walk's two lists of pixels still walking (Renderer._target "lists"): one entry per pixel at most.
LIST_IMAGES = ((1, "u4"), (1, "u4"))
_DTYPE_BYTES = {"f1": 1, "u4": 4, "f4": 4}


def frame_gpu_bytes(size: tuple[int, int]) -> int:
    """What the per-pixel targets of one frame allocate: the image (colour RGBA8 4 B, ids 16 B, geometry
    16 B), the shared depth buffer (4 B), the walk's state images (STATE_IMAGES: 100 B) and its lists
    (LIST_IMAGES: 8 B), the proxies' nearest hit so far (4 B); a proxies-path cost output adds 16 B per pixel
    while it is rendered."""
    state = sum(c * _DTYPE_BYTES[d] for c, d in (*STATE_IMAGES, *LIST_IMAGES))
    return int(size[0]) * int(size[1]) * (4 + 16 + 16 + 4 + state + 4)


def list_rectangle(count: int, size: tuple[int, int]) -> tuple[int, int, int]:
    """(width, height, blocks) of the rectangle a listed walk draw covers for ``count`` entries in a target
    of ``size`` (walk.frag: walked_pixel). blocks 1: entry 8b + i is pixel i of 4x2 block b, so the 8 lanes
    of a SIMD batch take consecutive entries; where that does not fit (a target under 4 pixels wide, or
    lists that need more rows than it has), rows of entries one after the other."""
    w, h = size
    width = w - w % 4
    if width:
        height = 2 * -(-count // (2 * width))
        if height <= h:
            return width, height, 1
    return w, -(-count // w), 0


def supersample_offsets(n: int) -> list[tuple[float, float]]:
    """n x n stratified sub-pixel offsets (pixel units, about the pixel centre)."""
    return [((i + 0.5) / n - 0.5, (j + 0.5) / n - 0.5) for j in range(n) for i in range(n)]


def _upscale(frame: Frame, size: tuple[int, int]) -> Frame:
    """Scale a reduced-resolution frame up: colour smoothly, everything else by nearest pixel."""
    from PIL import Image

    w, h = size
    out = Frame(draws=frame.draws, unfinished=frame.unfinished)
    if frame.color is not None:
        out.color = np.asarray(Image.fromarray(frame.color).resize(size, Image.BILINEAR))
    for name in ("coverage", "ids", "geom", "cost", "walk", "iters"):
        a = getattr(frame, name)
        if a is not None:
            ys = (np.arange(h) * a.shape[0] // h)[:, None]
            xs = (np.arange(w) * a.shape[1] // w)[None, :]
            setattr(out, name, a[ys, xs])
    return out


def _composite(rgba: np.ndarray, p: Params) -> tuple[np.ndarray, np.ndarray]:
    """Premultiplied fiber colour (8-bit levels, display space; the mean of several samples may be
    fractional) over the background, and the coverage."""
    bg = np.round(np.clip(np.asarray(p["look.background"]), 0, 1) ** (1 / 2.2) * 255)
    a = rgba[..., 3:4].astype(np.float64) / 255.0
    color = np.clip(np.round(rgba[..., :3] + (1.0 - a) * bg), 0, 255).astype(np.uint8)
    return color, a[..., 0].astype(np.float32)


def _read(fbo: moderngl.Framebuffer, attachment: int, components: int, dtype: str, size) -> np.ndarray:
    w, h = size
    np_dtype = {"f1": np.uint8, "u4": np.uint32, "f4": np.float32}[dtype]
    raw = fbo.read(viewport=(0, 0, w, h), components=components, attachment=attachment, dtype=dtype)
    return np.frombuffer(raw, np_dtype).reshape(h, w, components)[::-1].copy()
