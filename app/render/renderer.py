"""The virtual-fiber renderer: container proxies + the traversal shader + offscreen targets.

One renderer serves the command line, the viewer, the tests and the benchmarks. It never imports glfw: it
draws into whatever moderngl context it is given.

Per frame it draws every container segment once as an instanced screen rectangle (container.vert); the
fragment shader does the rest. Outputs (all read back top row first):

    color  (H, W, 3) uint8    shaded, tone-mapped sRGB
    ids    (H, W, 4) uint32   guide + 1 (0 = no fiber), ring, fiber, segment
    geom   (H, W, 4) float32  world normal xyz, distance along the ray (0 on a miss)
    cost   (H, W, 4) float32  fiber tests, arcs visited, container fragments, loop iterations (summed over
                              every container the pixel's ray enters: the work actually done)
    iters  (H, W)    float32  the most loop iterations any single shader invocation ran
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import moderngl
import numpy as np

from .. import reference
from . import look
from ..gl.shaders import ProgramCache
from ..params import ParamError, Params
from ..scene.containers import SEGMENT_BYTES, Scene
from .camera import Camera

MAX_RINGS = 64
# llvmpipe ends all loops of a fragment shader silently once they have made this many passes through loop
# headers in all; a loop's final, failing test is a pass too, so a loop of n iterations costs n + 1. The
# count is kept per SIMD batch of fragments, not per fragment: where lanes take different branches, the
# batch runs the loops of every branch taken, and a loop as often as its longest lane needs.
LOOP_CAP = 65_535
BRUTE_CHUNK = 60_000              # fibers per brute-force draw: stays under LOOP_CAP with 64 rings
MAX_SUB = 16                      # chord pieces per arc of a curved-fiber ring (glsl/fibers/curved.glsl)
# A ray visits a ring of curved fibers on one or two of three arcs (the first arc, then the second half or
# the back: glsl/fibers/shaped.glsl), so a batch whose lanes differ may visit it on all three; brute force
# tests every fiber of its chunk on each of up to MAX_SUB chord pieces of an arc, one pass of the candidate
# loop each plus each piece's final test. 16 passes per ring pay for the band, arc, piece and canary loops
# (the chunk is the one the old per-fiber chord loop used, which leaves the piece loops ample room).
BRUTE_CHUNK_SHAPED = (LOOP_CAP - 16 * MAX_RINGS) // (4 * (MAX_SUB + 2))
TWIST_PATTERNS = {"uniform": 0, "ramped": 1, "alternating": 2}
CURL_PATTERNS = {"helix": 0, "wave": 1}
SHADING_MODELS = {"kajiya_kay": 0, "marschner": 1}
SHADOW_MODES = {"off": 0, "density": 1, "traced": 2}
# standard MSAA sample positions (pixel units about the centre), as GL implementations place them
MSAA_PATTERNS = {
    2: [(4, 4), (-4, -4)],
    4: [(-2, -6), (6, -2), (-6, 2), (2, 6)],
    8: [(1, -3), (-1, 3), (5, 1), (-3, -5), (-5, 5), (-7, -1), (3, 7), (7, -7)],
}
MODES = {"fast": 0, "exact": 1, "brute": 2}

# The proxy rectangle's corners as two triangles (glsl/stages/container.vert places them per segment).
_QUAD = np.array([[0, 0], [1, 0], [1, 1], [0, 0], [1, 1], [0, 1]], dtype=np.float32)


@dataclass
class Frame:
    color: np.ndarray | None = None
    coverage: np.ndarray | None = None     # (H, W) float32: fraction of the pixel covered by fibers
    ids: np.ndarray | None = None
    geom: np.ndarray | None = None
    cost: np.ndarray | None = None
    iters: np.ndarray | None = None
    draws: int = 0

    @property
    def hit(self) -> np.ndarray:
        return self.ids[..., 0] > 0


def light_direction(p: Params) -> np.ndarray:
    az, el = math.radians(p["look.light_azimuth"]), math.radians(p["look.light_elevation"])
    return np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])


class Renderer:
    def __init__(self, ctx: moderngl.Context, programs: ProgramCache | None = None):
        self.ctx = ctx
        self.programs = programs or ProgramCache()
        self.scene: Scene | None = None
        self._quad = ctx.buffer(_QUAD.tobytes())
        self._instances: moderngl.Buffer | None = None
        self._vaos: dict[int, moderngl.VertexArray] = {}
        self._targets: dict[tuple, moderngl.Framebuffer] = {}
        self._parking = ctx.framebuffer(ctx.renderbuffer((1, 1)))   # bound while targets are released

    # --- scene -------------------------------------------------------------------------------------
    def set_scene(self, scene: Scene) -> None:
        """Upload the containers once. Nothing here depends on how many fibers are drawn."""
        if self._instances is not None:
            self._instances.release()
        for vao in self._vaos.values():
            vao.release()
        self._vaos.clear()
        self.scene = scene
        self._instances = self.ctx.buffer(scene.segments.tobytes())

    @property
    def scene_gpu_bytes(self) -> int:
        """Bytes of GPU buffers that hold the scene: container segments plus the shared proxy rectangle."""
        return (self._instances.size if self._instances else 0) + self._quad.size

    def render_quality(self, p: Params, cam: Camera, size: tuple[int, int], *, outputs=("color",),
                       mode: str | None = None) -> Frame:
        """Render honouring quality.render_scale too: cast fewer rays and scale the picture up."""
        scale = p["quality.render_scale"]
        inner = (max(1, round(size[0] * scale)), max(1, round(size[1] * scale)))
        frame = self.render(p, cam, inner, outputs=outputs, mode=mode)
        if inner != tuple(size):
            frame = _upscale(frame, size)
        return frame

    def _vao(self, program: moderngl.Program) -> moderngl.VertexArray:
        key = id(program)
        if key not in self._vaos:
            self._vaos[key] = self.ctx.vertex_array(program, [
                (self._quad, "2f", "in_quad"),
                (self._instances, "4f 4f 4f 4f 4f/i", "in_a", "in_b", "in_c", "in_d", "in_e"),
            ])
        return self._vaos[key]

    # --- targets -----------------------------------------------------------------------------------
    def _target(self, size: tuple[int, int], cost: bool) -> moderngl.Framebuffer:
        key = (size, cost)
        if key not in self._targets:
            if cost:
                att = [self.ctx.texture(size, 4, dtype="f4")]
                self._targets[key] = self.ctx.framebuffer(att)
            else:
                att = [self.ctx.texture(size, 4, dtype="f1"), self.ctx.texture(size, 4, dtype="u4"),
                       self.ctx.texture(size, 4, dtype="f4")]
                self._targets[key] = self.ctx.framebuffer(att, self.ctx.depth_renderbuffer(size))
        return self._targets[key]

    def targets(self, size: tuple[int, int]) -> moderngl.Framebuffer:
        """The framebuffer ``render`` draws into at ``size``: colour (premultiplied RGBA8), ids (RGBA32UI),
        geometry (RGBA32F) and depth. The viewer displays its colour texture without a read-back."""
        return self._target((int(size[0]), int(size[1])), cost=False)

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

    def _msaa_targets(self, size: tuple[int, int], samples: int):
        key = (size, "msaa", samples)
        if key not in self._targets:
            ms = self.ctx.framebuffer([self.ctx.renderbuffer(size, 4, samples=samples)],
                                      self.ctx.depth_renderbuffer(size, samples=samples))
            resolved = self.ctx.framebuffer([self.ctx.texture(size, 4, dtype="f1")])
            self._targets[key] = ms
            self._targets[key + ("resolved",)] = resolved
        return self._targets[key], self._targets[key + ("resolved",)]

    def release_targets(self) -> None:
        release_framebuffers(self._parking, self._targets)

    # --- drawing -----------------------------------------------------------------------------------
    def program(self, p: Params, mode: str, cost: bool, supersample: int = 1,
                msaa: int = 0) -> moderngl.Program:
        defines = {"TRAVERSAL": MODES[mode], "MAX_RINGS": MAX_RINGS, "MAX_SUB": MAX_SUB,
                   "HASH_THESIS": int(p["fibers.hash"] == "thesis"), "COST_PASS": int(cost),
                   "SHAPED": int(is_shaped(p)), "SHAPE_CURL": shape_curl_define(p),
                   "SHAPE_ELLIPSOID": int(p["shape.ellipsoid"] > 0), "SHAPE_TWIST": int(p["shape.twist"] != 0),
                   "SHADING_MODEL": SHADING_MODELS[p["look.model"]],
                   "SHADOW_MODE": SHADOW_MODES[p["look.self_shadow"]], "SUPERSAMPLE": supersample,
                   "MSAA_SAMPLES": msaa}
        return self.programs.get(self.ctx, "stages/container.vert", "stages/container.frag", defines)

    def _set_uniforms(self, prog: moderngl.Program, p: Params, cam: Camera, size, offset) -> None:
        lay = reference.ring_layout(p)
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
            "uExposureScale": 2.0 ** p["look.exposure"], "uFiberDensity": look.fiber_density(p, lay.fibers_per_container),
            "uTintVariation": p["look.tint_variation"], "uRoughnessVariation": p["look.roughness_variation"],
            "uShadowDensity": p["look.shadow_density"],
            "uEllipsoid": p["shape.ellipsoid"], "uTwist": p["shape.twist"],
            "uTwistPattern": TWIST_PATTERNS[p["shape.twist_pattern"]],
            "uCurlAmplitude": p["shape.curl_amplitude"] / K, "uCurlFrequency": p["shape.curl_frequency"],
            "uCurlPattern": CURL_PATTERNS[p["shape.curl_pattern"]],
        }
        for name, value in values.items():
            if name in prog:
                prog[name].value = value
        samples = np.zeros((16, 2), np.float32)
        pattern = MSAA_PATTERNS.get(p["quality.msaa"])
        if pattern:
            samples[:len(pattern)] = np.array(pattern) / 16.0
        for name, arr in (*ring_uniforms(lay).items(), ("uSampleOffsets", samples)):
            if name in prog:
                prog[name].write(arr.tobytes())
        if "uClipFromCamera" in prog:
            prog["uClipFromCamera"].write(cam.clip_from_camera(w / h).T.copy().tobytes())

    def _draw(self, prog: moderngl.Program, p: Params, mode: str, rays: int | None = None) -> int:
        """Draw every container, once per range of ``draw_ranges`` (brute mode: chunks of each container's
        fibers; fast and exact: one draw unless a traversal could pass the loop budget). ``rays``: traversals
        per fragment (default: the most ``p`` can ask for). Returns the draw count."""
        vao = self._vao(prog)
        rays = traversals_per_fragment(p, mode) if rays is None else rays
        ranges = draw_ranges(p, self.scene, mode, rays)
        if "uRingOrder" in prog:
            prog["uRingOrder"].value = int(len(ranges) > 1 or needs_ring_order(p, self.scene, mode, rays))
        for start, end in ranges:
            for name in ("uBruteRange", "uFiberRange"):
                if name in prog:
                    prog[name].value = (start, end)
            vao.render(moderngl.TRIANGLES, instances=self.scene.n_segments)
        return len(ranges)

    def render(self, p: Params, cam: Camera, size: tuple[int, int], *, outputs=("color",),
               offset=(0.0, 0.0), mode: str | None = None, antialias: bool = True) -> Frame:
        """Render the scene. ``outputs`` is any of color, ids, geom, cost, iters, draw (no read-back).

        With ``antialias``, colour honours quality.supersample (n x n rays per pixel in the shader) or
        quality.msaa (one ray per MSAA sample, shaded once). Brute force always casts one ray per pixel:
        it is the reference for ids, and n^2 rays would cost n^2 times its loop budget.
        """
        if self.scene is None:
            raise RuntimeError("Renderer.render: call set_scene first")
        mode = mode or p["quality.mode"]
        ctx = self.ctx
        frame = Frame()
        size = (int(size[0]), int(size[1]))
        self.prepare_state()
        supersample = p["quality.supersample"] if antialias and mode != "brute" else 1
        msaa = self._msaa_samples(p) if antialias and mode != "brute" else 0
        # "draw" renders the frame without reading anything back (timing, the viewer's own display)
        wants_pass = {"ids", "geom", "draw"} & set(outputs) or ("color" in outputs and not msaa)
        if wants_pass:
            fbo = self._target(size, cost=False)
            fbo.use()
            ctx.viewport = (0, 0) + size
            clear_targets(fbo)
            ctx.enable(moderngl.DEPTH_TEST)
            ctx.depth_func = "<"
            prog = self.program(p, mode, cost=False, supersample=supersample)
            self._set_uniforms(prog, p, cam, size, offset)
            frame.draws += self._draw(prog, p, mode)
            if "color" in outputs and not msaa:
                frame.color, frame.coverage = _composite(_read(fbo, 0, 4, "f1", size), p)
            if "ids" in outputs:
                frame.ids = _read(fbo, 1, 4, "u4", size)
            if "geom" in outputs:
                frame.geom = _read(fbo, 2, 4, "f4", size)
        if "color" in outputs and msaa:
            ms, resolved = self._msaa_targets(size, msaa)
            ms.use()
            ctx.viewport = (0, 0) + size
            ms.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
            ctx.enable(moderngl.DEPTH_TEST)
            ctx.depth_func = "<"
            prog = self.program(p, mode, cost=False, msaa=msaa)
            self._set_uniforms(prog, p, cam, size, offset)
            frame.draws += self._draw(prog, p, mode)
            ctx.copy_framebuffer(resolved, ms)
            frame.color, frame.coverage = _composite(_read(resolved, 0, 4, "f1", size), p)
        for kind in ("cost", "iters"):
            if kind not in outputs:
                continue
            fbo = self._target(size, cost=True)
            fbo.use()
            ctx.viewport = (0, 0) + size
            fbo.clear(0.0, 0.0, 0.0, 0.0)
            ctx.disable(moderngl.DEPTH_TEST)
            ctx.enable(moderngl.BLEND)
            ctx.blend_func = moderngl.ONE, moderngl.ONE
            ctx.blend_equation = moderngl.FUNC_ADD if kind == "cost" else moderngl.MAX
            prog = self.program(p, mode, cost=True)
            self._set_uniforms(prog, p, cam, size, offset)
            frame.draws += self._draw(prog, p, mode)
            data = _read(fbo, 0, 4, "f4", size)
            if kind == "cost":
                frame.cost = data
            else:
                frame.iters = data[..., 3]
            ctx.blend_equation = moderngl.FUNC_ADD
            ctx.disable(moderngl.BLEND)
        return frame


EPS_ANGLE = 2e-5                        # glsl/common/epsilon.glsl


def ring_uniforms(lay: reference.RingLayout) -> dict[str, np.ndarray]:
    """The per-ring uniform arrays of glsl/fibers/layout.glsl, padded to MAX_RINGS. Besides the layout,
    uRingB carries what the traversal would otherwise divide for per arc: 1 / dphi, and how many
    candidates past an improvement can still be nearer (2 reaches, traverse.glsl)."""
    K = lay.rings
    ring_a = np.zeros((MAX_RINGS, 4), np.float32)
    ring_b = np.zeros((MAX_RINGS, 4), np.float32)
    ring_n = np.zeros((MAX_RINGS, 2), np.int32)
    ring_a[:K] = np.stack([lay.rho, lay.dphi, lay.rot, lay.reach], 1)
    after = np.floor(2.0 * (lay.reach + EPS_ANGLE) / lay.dphi * (1.0 + 1e-6)) + 1.0
    ring_b[:K] = np.stack([lay.max_dr, lay.max_dphi, 1.0 / lay.dphi, after], 1)
    ring_n[:K, 0], ring_n[:K, 1] = lay.n, lay.first
    return {"uRingA": ring_a, "uRingB": ring_b, "uRingN": ring_n}


def traversals_per_fragment(p: Params, mode: str) -> int:
    """The most traversals one fragment can run: a ray per supersample or MSAA sample (brute casts one),
    twice that with traced shadows (each hit sends a shadow ray through the same container)."""
    rays = 1 if mode == "brute" else max(p["quality.supersample"] ** 2, p["quality.msaa"], 1)
    return rays * (2 if p["look.self_shadow"] == "traced" else 1)


# Loop passes one traversal may spend in fast and exact modes, per draw: what the budget leaves once the
# shading, the loop canary and rounding in the bound below are paid for.
LOOP_HEADROOM = 1024


def candidate_caps(p: Params, scene: Scene) -> tuple[np.ndarray, int]:
    """Per ring, the most fibers one piece (arc) of a ray can test in fast and exact modes, and the loop
    passes one test costs. Mirrors the candidate windows of glsl/fibers/traverse.glsl: a piece of ring i
    runs between the ring's outer circle and its inner circle or the ray's closest approach to the axis;
    seen from the axis it sweeps at most acos(inner / outer). The window adds the ring's reach on either
    side. Curved fibers: per ring the loop passes of one arc, all its chord pieces included, and 1
    (``_shaped_arc_passes``)."""
    lay = reference.ring_layout(p)
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
    the slots within the ring's reach of the angles its chord sweeps in the ring's frame, which turns with
    the twist. Seen from the axis an arc of the untwisted path sweeps at most acos(inner / outer); the
    twist adds what it turns over the arc, so all pieces together sweep at most that plus the twist over
    the segment, and each piece adds its two reaches. A piece turns at most sqrt(0.8 r_f / r) with the
    twist (the chord rule, curved.glsl), or a MAX_SUB-th of the segment's twist where the rule is capped;
    a chord that sweeps more than 2.5 radians takes every fiber of the ring."""
    lay = reference.ring_layout(p)
    sh = reference.Shape.from_params(p)
    seg = scene.segments.astype(np.float64)
    axis = seg[:, 4:7] - seg[:, 0:3]
    h = np.linalg.norm(axis, axis=1)
    ez = axis / h[:, None]

    def slope(n):                                   # container.glsl: joint_slope
        c = np.abs((n * ez).sum(1))
        return np.sqrt(np.maximum(0.0, 1.0 - c * c)) / np.maximum(c, 1e-6)

    r_bound = np.maximum(seg[:, 3], seg[:, 7])
    z_lo, z_hi = -r_bound * slope(seg[:, 8:11]), h + r_bound * slope(seg[:, 12:15])
    v_lo = seg[:, 11] + (seg[:, 15] - seg[:, 11]) * z_lo / h   # the guide parameter over the slab
    v_hi = seg[:, 11] + (seg[:, 15] - seg[:, 11]) * z_hi / h
    e_lo = float(np.min(np.minimum(reference.shape_scale(sh, v_lo), reference.shape_scale(sh, v_hi))))
    grow = lay.fiber_radius + sh.curl_amplitude + 1e-6      # shaped.glsl: ring_band
    inner = np.maximum(0.0, e_lo * (lay.rho - lay.max_dr) - grow)
    outer = (lay.rho + lay.max_dr) + grow                   # e_hi <= 1
    closest = np.minimum.accumulate(inner)              # no ring deeper than the ray's closest approach
    sweep = np.arccos(np.clip(closest / outer, 0.0, 1.0)) + 1e-3
    dv = np.abs(v_hi - v_lo) * (2.0 * np.maximum(np.abs(v_lo), np.abs(v_hi)) if sh.twist_pattern == 1
                                else 1.0)
    twist = 2.0 * math.pi * abs(sh.twist) * float(dv.max()) * 1.001
    r_chord = lay.rho + lay.max_dr + lay.fiber_radius + sh.curl_amplitude   # curved.glsl: chord_pieces
    piece_turn = np.minimum(twist, np.maximum(np.sqrt(0.8 * max(lay.fiber_radius, 1e-30) / r_chord) * 1.001,
                                              twist / MAX_SUB))
    d_min = e_lo * (lay.rho - lay.max_dr)           # shaped.glsl: shaped_reach
    r = lay.fiber_radius + sh.curl_amplitude
    with np.errstate(divide="ignore", invalid="ignore"):
        disc = np.where(d_min > r, np.arcsin(np.minimum(1.0, r / d_min)), math.pi)
    reach = lay.max_dphi + disc + EPS_ANGLE
    per_piece = np.floor(2.0 * reach / lay.dphi).astype(np.int64) + 2
    swept = np.floor((sweep + twist) / lay.dphi).astype(np.int64) + MAX_SUB * per_piece
    whole = sweep + piece_turn > 2.5 - 1e-3                 # shaped.glsl: the near-axis chord takes all
    tests = np.where(whole, MAX_SUB * lay.n, np.minimum(MAX_SUB * lay.n, swept))
    return tests + 2 * MAX_SUB + 1          # each piece's header and its candidate loop's final test


def _loop_budget(p: Params, rays: int) -> int:
    """Loop passes one traversal may spend in one draw: the budget less the shading's share and the
    ring, arc and canary loops."""
    return (LOOP_CAP - LOOP_HEADROOM) // max(1, rays) - (16 * p["fibers.rings"] + 16)


def needs_ring_order(p: Params, scene: Scene, mode: str, rays: int = 1) -> bool:
    """Whether one draw of every fiber needs the traversal's loops after the ring loop to go by ring index
    (uRingOrder). Each lane's own order is cheaper, but then lanes of a batch can visit different rings at
    one iteration, and the batch pays the costliest ring's candidates at every iteration: fronts and
    first halves by ring, plus up to K times the costliest ring for the loops after (twice for curved)."""
    if mode == "brute":
        return False
    caps, per_test = candidate_caps(p, scene)
    tests = per_test * caps
    if not is_shaped(p):
        worst = tests.sum() + (p["fibers.rings"] + 1) * tests.max()
    else:
        worst = 2 * tests.sum() + 2 * p["fibers.rings"] * tests.max()
    return bool(worst > _loop_budget(p, rays))


def draw_ranges(p: Params, scene: Scene, mode: str, rays: int = 1) -> list[tuple[int, int]]:
    """Ranges [start, end) of a container's flat fiber numbering, one draw each, such that no SIMD batch of
    fragments passes llvmpipe's loop budget: it would stop every loop in silence and lose fibers.

    Brute force tests each fiber of its chunk once (straight) or on each chord piece of each arc (curved).
    Fast and exact test a ring's candidates on each piece of the ray in that ring, at most
    ``candidate_caps`` of them (curved: the loop passes of one arc, all its chord pieces included). A batch
    visits a straight ring on its front and back pieces, and the deepest pieces of its lanes (any ring, the
    costliest one bounds them); a curved ring on up to three arcs (glsl/fibers/shaped.glsl). Rings are packed into draws greedily, a
    ring split when it alone is too much. Every bundled layout needs one draw; 64 rings of 0.01 degree
    fibers, or curled fibers whose reach is the whole ring, need several, and the depth test keeps the
    nearest hit across them as it does in brute mode. The bound holds with the loops after the ring loop
    (curved: the arcs) in ring order (uRingOrder), which ``Renderer._draw`` sets whenever there is more than one draw or
    ``needs_ring_order``. ``rays``: traversals per fragment."""
    lay = reference.ring_layout(p)
    total = lay.fibers_per_container
    if mode == "brute":
        chunk = BRUTE_CHUNK_SHAPED if is_shaped(p) else BRUTE_CHUNK
        return [(start, min(total, start + chunk)) for start in range(0, total, chunk)]
    caps, per_test = candidate_caps(p, scene)
    budget = _loop_budget(p, rays)
    shaped = is_shaped(p)
    # per ring: arcs a batch may visit it on; per draw: deepest pieces, at the draw's costliest ring
    visits, deepest = (2, 2) if not shaped else (3, 0)

    def cost(i: int, m: int) -> int:
        """Loop passes of one visit of ring i with m of its fibers in the draw."""
        if shaped:      # every piece tests at most the share, and pays its header and final test
            return min(int(caps[i]), MAX_SUB * (m + 2) + 1)
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
                fit = ((budget - used) // visits - 2 * MAX_SUB - 1) // MAX_SUB
            else:
                fit = (budget - used - deepest * top) // ((visits + deepest) * per_test)
            if fit > 0:
                pos, left = pos + fit, left - fit
            if pos > start:
                ranges.append((start, pos))
            start, used, top = pos, 0, 0
    ranges.append((start, total))
    return ranges


def shape_curl_define(p: Params) -> int:
    """What the shaped traversal builds in for the curl (glsl/fibers/shape.glsl): 0 none, 1 helix, 2 wave."""
    return 0 if p["shape.curl_amplitude"] <= 0 else 1 + CURL_PATTERNS[p["shape.curl_pattern"]]


def is_shaped(p: Params) -> bool:
    """Curved fibers need the slower curved-fiber traversal; straight ones keep the fast path."""
    return p["shape.ellipsoid"] > 0 or p["shape.curl_amplitude"] > 0 or p["shape.twist"] != 0


def clear_targets(fbo: moderngl.Framebuffer) -> None:
    """Zero every colour attachment and set depth to 1. moderngl clears each attachment with the
    glClearBuffer call of its type (uiv for the integer ids, fv for the others: tests/test_gl_infra.py), so
    the integer target is cleared as GL defines, where glClear would leave it undefined."""
    fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)


def release_framebuffers(parking: moderngl.Framebuffer, targets: dict) -> None:
    """Release framebuffers and their attachments. A live ``parking`` framebuffer is bound first: moderngl
    rebinds the current framebuffer whenever it creates one, and rebinding a released one is an invalid
    operation that the next test or frame would inherit."""
    parking.use()
    for fbo in targets.values():
        for a in fbo.color_attachments:
            a.release()
        if fbo.depth_attachment:
            fbo.depth_attachment.release()
        fbo.release()
    targets.clear()


def scene_gpu_bytes(scene: Scene) -> int:
    """What ``Renderer.set_scene`` allocates for ``scene``: the segments plus the shared proxy rectangle."""
    return scene.nbytes + _QUAD.nbytes


def supersample_offsets(n: int) -> list[tuple[float, float]]:
    """n x n stratified sub-pixel offsets (pixel units, about the pixel centre)."""
    return [((i + 0.5) / n - 0.5, (j + 0.5) / n - 0.5) for j in range(n) for i in range(n)]


def _upscale(frame: Frame, size: tuple[int, int]) -> Frame:
    """Scale a reduced-resolution frame up: colour smoothly, everything else by nearest pixel."""
    from PIL import Image

    w, h = size
    out = Frame(draws=frame.draws)
    if frame.color is not None:
        out.color = np.asarray(Image.fromarray(frame.color).resize(size, Image.BILINEAR))
    for name in ("coverage", "ids", "geom", "cost", "iters"):
        a = getattr(frame, name)
        if a is not None:
            ys = (np.arange(h) * a.shape[0] // h)[:, None]
            xs = (np.arange(w) * a.shape[1] // w)[None, :]
            setattr(out, name, a[ys, xs])
    return out


def _composite(rgba: np.ndarray, p: Params) -> tuple[np.ndarray, np.ndarray]:
    """Premultiplied fiber colour over the background (8-bit, display space), and the coverage."""
    bg = np.round(np.clip(np.asarray(p["look.background"]), 0, 1) ** (1 / 2.2) * 255)
    a = rgba[..., 3:4].astype(np.float64) / 255.0
    color = np.clip(np.round(rgba[..., :3] + (1.0 - a) * bg), 0, 255).astype(np.uint8)
    return color, a[..., 0].astype(np.float32)


def _read(fbo: moderngl.Framebuffer, attachment: int, components: int, dtype: str, size) -> np.ndarray:
    w, h = size
    np_dtype = {"f1": np.uint8, "u4": np.uint32, "f4": np.float32}[dtype]
    raw = fbo.read(viewport=(0, 0, w, h), components=components, attachment=attachment, dtype=dtype)
    return np.frombuffer(raw, np_dtype).reshape(h, w, components)[::-1].copy()
