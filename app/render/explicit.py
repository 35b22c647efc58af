"""The conventional baseline: every fiber generated in numpy, stored in GPU buffers, rasterized as ribbons.

The virtual renderer stores containers only and ray casts the fibers per pixel. This module is the other
side of that trade, kept apart from it (the scene never holds per-fiber data; this renderer does). It draws
*the same fibers*: the placement comes from the same ring layout and the same hash as the shader
(``app.fibers``: ``ring_layout``, and ``fiber_key``/``key_random``, the GLSL's factored hash; checked against
``reference.all_fibers`` by the tests), mapped through the same container segments.

Geometry, in words. Inside a container segment a virtual fiber is the vertical line (cx, cy) of unit space,
so in the segment's local frame it is P(z) = p0 + w(z) (cx ex + cy ey) + z ez with w(z) = r0 + kappa z: a
straight line in the world, clipped by the segment's root-side and tip-side joint planes, and cut at the
height where the guide parameter reaches the fiber's v_end. With t = z / h that is

    P(t) = mix(p0, p1, t) + mix(r0, r1, t) * d,   d = cx ex + cy ey  (world axes, |d| = |c| <= 1)

for t in [t0, t1]. So each (segment, fiber) pair is one instance: d, t0 and t1 in half floats, plus the
fiber's tint and roughness (8 bits each) -- 12 bytes -- and each segment row is stored once (the scene's
80-byte row: ends, radii, joint planes, guide) and read per instance with an attribute divisor of F (fibers
per container).
Storing d and t, both O(1), rather than positions keeps half floats accurate at any scene scale: the error
is ~2^-12 of the container radius across the fiber (about 2% of a default fiber's radius) and ~2^-12 of
the segment's length along it. A fiber that is cut before a segment gets t0 = t1 there (no area).

Drawing: one instanced draw of 4-vertex triangle strips; the vertex shader expands each end sideways,
facing the camera, by the fiber's radius (fiber_radius * w); a ribbon end on a joint plane is lengthened to
the plane and both joint planes clip the ribbon (gl_ClipDistance), so the ribbons of two segments meet on
the plane where a square end would leave a wedge open or overlap. The fragment shader rebuilds the round
fiber's normal across the ribbon and shades with the virtual renderer's shading files (the same joint-
blended tangent, shading/tangent.glsl). Depth is the rasterizer's, so the early depth test stays on; along
one ray the order of depths is the order of distances, so the nearest fiber wins, as in the ray caster.

Thin fibers (quality.filter = coverage, ``_filtered_color``): the virtual filter's treatment, for a fair
A/B. Each ribbon is widened by the footprint (a tent of quality.filter_width pixels' half-width at its
distance) and each fragment's alpha is the share of the footprint its fiber covers (the same
footprint_coverage as glsl/fibers/coverage.glsl). Dense hair puts hundreds of such fragments in a pixel,
so they are composited without sorting: the nearest fragment's distance, then the optical depth summed into
BINS depth bins behind it, then each fragment's colour weighted by its alpha and the light the bins in front
of it let through; a fullscreen pass puts each pixel's opaque depth into the depth buffer first, so the
colour pass shades only what can show (llvmpipe skips nothing for a discard). Weighted blended OIT (one
colour pass, weights by depth alone) was measured and not kept: its weights cannot know how opaque the
fibers in front are (docs/antialias.md, "The explicit baseline"). Ids and depth stay the opaque ribbons'.

Why vertex attributes rather than storage-buffer pulling: on llvmpipe the attribute fetch is compiled into
the vertex pipeline and was about 10x faster than pulling the same data from storage buffers by
gl_VertexID (86,400 fibers: 0.24 s against ~0.025 s of vertex work); a hardware GPU would not care.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass

import moderngl
import numpy as np

from .. import fibers
from ..errors import VfiberError
from ..fibers import MAX_RINGS, fiber_key, key_random
from ..gl.shaders import ProgramCache
from ..params import Params
from ..units import human_bytes
from ..scene.containers import SEGMENT_BYTES, Scene
from . import look
from .camera import Camera
from .renderer import Frame, clear_targets, light_direction, release_framebuffers

DEFAULT_BUDGET_BYTES = 1 << 30     # 1 GiB of fiber buffers; on llvmpipe "GPU" memory is system memory
# quality.filter = coverage (ribbon.vert/.frag FILTER): the depth bins a pixel's fragments are composited
# by, each BIN_RADII of the scene's median container radius deep, behind the pixel's nearest fragment
BINS = 16
BIN_RADII = 0.5
COMPOSITES = {"bins": 0, "weighted": 1}    # depth-binned transmittance (used) or weighted blended OIT
INSTANCE_BYTES = 12                # per (segment, fiber): half4(d.xyz, t0), half t1, uint16 tint | rough
TAPER_BYTES = 2                    # per (segment, fiber) when fibers taper: half v_end (the fiber's own end)
ROW_BYTES = SEGMENT_BYTES          # per segment row: the scene's own row (p0 r0, p1 r1, n0 v0, n1 v1, fx guide)
GEN_INSTANCES = 1 << 18            # (segment, fiber) pairs generated per numpy batch: bounds temporaries
MAX_INSTANCES = 2**31 - 1          # gl_InstanceID is a signed int

# The parameters the explicit geometry depends on: change one and the fibers must be rebuilt.
GEOMETRY_KEYS = ("fibers.rings", "fibers.phi_step", "fibers.phi_increment", "fibers.even_spacing",
                 "fibers.radial_jitter", "fibers.angular_jitter", "fibers.length_jitter", "fibers.hash",
                 "fibers.seed")
# Shape parameters that bend fibers inside a container. The baseline draws straight fibers (so does the
# virtual shader today); ``ignored_shape`` names those set, so a comparison can say what it left out.
SHAPE_KEYS = ("shape.ellipsoid", "shape.curl_amplitude", "shape.twist", "shape.frizz", "shape.noise")


class ExplicitBudgetError(VfiberError, MemoryError):
    """The explicit fibers would need more GPU memory than the budget allows; nothing was allocated."""

    def __init__(self, needed: int, budget: int, fibers: int, per_fiber: float):
        self.needed, self.budget, self.fibers = needed, budget, fibers
        most = int(budget // per_fiber) if per_fiber > 0 else 0
        super().__init__(
            f"explicit fibers need {human_bytes(needed)} of GPU buffers for {fibers:,} fibers "
            f"({per_fiber:.1f} bytes each), over the {human_bytes(budget)} budget: the explicit method refuses "
            f"rather than exhaust the machine. Fit at most ~{most:,} fibers (fewer containers or rings, a "
            f"larger fibers.phi_step), raise the budget (ExplicitRenderer(ctx, budget_bytes=...)), or use the "
            f"virtual method, whose memory does not grow with the number of fibers.")


# --------------------------------------------------------------------------------------------------
# Sizes, known before anything is generated
# --------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Plan:
    rows: int                      # container segments
    guides: int                    # distinct guides (chains of segments)
    fibers_per_container: int
    tapered: bool = False          # strand.tip_width < 1: each instance also stores its fiber's v_end

    @property
    def fibers(self) -> int:
        """Fibers drawn: one per guide and layout slot (a fiber runs through every segment of its guide)."""
        return self.guides * self.fibers_per_container

    @property
    def instances(self) -> int:
        return self.rows * self.fibers_per_container

    @property
    def gpu_bytes(self) -> int:
        return explicit_bytes(self.fibers_per_container, self.rows, self.tapered)

    @property
    def bytes_per_fiber(self) -> float:
        return self.gpu_bytes / max(1, self.fibers)


def explicit_bytes(fibers_per_container: int, n_segments: int, tapered: bool = False) -> int:
    """GPU bytes ``ExplicitRenderer.set_scene`` allocates for these fibers: one instance per fiber per
    container segment and each segment's row once (at least one of each: a GL buffer cannot be empty), and
    for tapered fibers (strand.tip_width < 1) each instance's v_end. The one formula for "explicit bytes":
    ``vfiber info``, the viewer and the budget all use it."""
    per_instance = INSTANCE_BYTES + (TAPER_BYTES if tapered else 0)
    return (max(1, int(n_segments) * int(fibers_per_container)) * per_instance
            + max(1, int(n_segments)) * ROW_BYTES)


EXPLICIT_FORMULA = (f"explicit = fibers per container x container segments x {INSTANCE_BYTES} bytes + container "
                    f"segments x {ROW_BYTES} bytes (what the explicit baseline allocates: per fiber per segment "
                    f"its offset and clip range in half floats, tint and roughness; each segment's row once)")


def plan(scene: Scene, p: Params) -> Plan:
    guides = len(np.unique(scene.segments[:, 19])) if scene.n_segments else 0
    return Plan(scene.n_segments, guides, fibers.ring_layout(p).fibers_per_container, fibers.tapered(p))


def estimate_bytes(scene: Scene, p: Params) -> int:
    """Exact bytes of GPU buffers ``ExplicitRenderer.set_scene(scene, p)`` would allocate."""
    return plan(scene, p).gpu_bytes


# --------------------------------------------------------------------------------------------------
# Fiber generation in numpy
# --------------------------------------------------------------------------------------------------
def fiber_centers(lay: fibers.RingLayout, guides: np.ndarray):
    """Unit-space centres and shading randoms of every fiber of ``guides`` (G,): arrays (G, F).

    Returns (cx, cy, v_end, tint, rough); equal to ``fibers.fiber_center`` fiber by fiber. The key is
    hashed once per fiber (``fiber_key``), each channel one round more, rather than five rounds a channel.
    """
    F = lay.fibers_per_container
    ring = np.repeat(np.arange(lay.rings), lay.n)
    j = np.arange(F) - np.repeat(lay.first, lay.n)
    key = fiber_key(lay.seed, np.asarray(guides, np.uint32)[:, None], ring[None], j[None])
    if lay.thesis_hash:
        slot_deg = np.degrees(lay.rot[ring] + j * lay.dphi[ring])
        ur, ua, ul = (np.broadcast_to(fibers.thesis_random(slot_deg, ring, ch), key.shape)
                      for ch in (fibers.CH_RADIAL, fibers.CH_ANGULAR, fibers.CH_LENGTH))
    else:
        ur, ua, ul = fibers.key_randoms(key)
    radius = lay.rho[ring] + (2.0 * ur - 1.0) * lay.max_dr[ring]
    angle = lay.rot[ring] + j * lay.dphi[ring] + (2.0 * ua - 1.0) * lay.max_dphi[ring]
    v_end = 1.0 - lay.length_jitter * ul
    tint = key_random(key, fibers.CH_TINT)
    rough = key_random(key, fibers.CH_ROUGH)
    return radius * np.cos(angle), radius * np.sin(angle), v_end, tint, rough


@dataclass
class _Frames:
    """Per segment row, float64, shapes (R, 3) or (R,): what ``reference.segment`` computes, batched."""
    p0: np.ndarray
    p1: np.ndarray
    ex: np.ndarray
    ey: np.ndarray
    ez: np.ndarray
    h: np.ndarray
    r0: np.ndarray
    r1: np.ndarray
    n0: np.ndarray
    n1: np.ndarray
    v0: np.ndarray
    v1: np.ndarray

    @staticmethod
    def of(rows: np.ndarray) -> _Frames:
        rows = rows.astype(np.float64)
        p0, p1 = rows[..., 0:3], rows[..., 4:7]
        axis = p1 - p0
        h = np.linalg.norm(axis, axis=-1)
        ez = axis / h[..., None]
        fx = rows[..., 16:19]
        ex = fx - ez * np.sum(fx * ez, -1, keepdims=True)
        ex /= np.linalg.norm(ex, axis=-1, keepdims=True)
        ey = np.cross(ez, ex)
        return _Frames(p0, p1, ex, ey, ez, h, rows[..., 3], rows[..., 7], rows[..., 8:11], rows[..., 12:15],
                       rows[..., 11], rows[..., 15])


def _plane_z(fr: _Frames, cx: np.ndarray, cy: np.ndarray, n: np.ndarray, on_tip: bool) -> np.ndarray:
    """Local height (R, F) where fiber (cx, cy) crosses its segment's root plane (n0 through p0) or tip
    plane (n1 through p1). P(z) = p0 + (r0 + kappa z)(cx ex + cy ey) + z ez, so n . (P(z) - A) = 0 is
    linear in z."""
    q = cx * np.sum(fr.ex * n, -1)[:, None] + cy * np.sum(fr.ey * n, -1)[:, None]
    en = np.sum(fr.ez * n, -1)[:, None]
    h = fr.h[:, None]
    kappa = ((fr.r1 - fr.r0) / fr.h)[:, None]
    offset = -h * en if on_tip else 0.0          # n . (p0 - A)
    with np.errstate(divide="ignore", invalid="ignore"):
        z = -(offset + fr.r0[:, None] * q) / (kappa * q + en)
    return np.where(np.isfinite(z), z, h if on_tip else 0.0)


def segment_fibers(scene: Scene, lay: fibers.RingLayout, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every fiber of the segment rows ``rows`` (R,): the (R*F, 6) uint16 instance records (half d.xyz,
    half t0, half t1, tint | rough << 8) and (R, F) t1 - t0 (0 where the fiber is absent)."""
    fr = _Frames.of(scene.segments[rows])
    guides = scene.segments[rows, 19].astype(np.uint32)
    cx, cy, v_end, tint, rough = fiber_centers(lay, guides)                 # (R, F)
    z0 = _plane_z(fr, cx, cy, fr.n0, on_tip=False)
    z1 = _plane_z(fr, cx, cy, fr.n1, on_tip=True)
    v0, v1, h = fr.v0[:, None], fr.v1[:, None], fr.h[:, None]
    # a fiber stops where the guide parameter reaches v_end: never before the segment starts, nor past it
    z_cut = (v_end - v0) / (v1 - v0) * h
    z1 = np.where(v_end < v1, np.clip(z_cut, z0, np.maximum(z0, z1)), z1)
    z1 = np.where(v_end <= v0, z0, z1)                                       # cut in an earlier segment
    R, F = cx.shape
    out = np.empty((R, F, 6), np.uint16)
    half = np.empty((R, F, 5), np.float16)
    half[..., 0] = cx * fr.ex[:, None, 0] + cy * fr.ey[:, None, 0]
    half[..., 1] = cx * fr.ex[:, None, 1] + cy * fr.ey[:, None, 1]
    half[..., 2] = cx * fr.ex[:, None, 2] + cy * fr.ey[:, None, 2]
    half[..., 3] = z0 / h
    half[..., 4] = z1 / h
    half[..., 4] = np.where(v_end <= v0, half[..., 3], half[..., 4])         # exactly no length
    out[..., :5] = half.view(np.uint16)
    q8 = lambda u: np.minimum(255, np.round(u * 255.0)).astype(np.uint16)  # noqa: E731
    out[..., 5] = q8(tint) | (q8(rough) << np.uint16(8))
    return out.reshape(-1, 6), (z1 - z0) / h


def fiber_ends(scene: Scene, lay: fibers.RingLayout, rows: np.ndarray) -> np.ndarray:
    """Where each fiber of the segment rows ``rows`` ends along its guide (v_end), (R*F,) half floats: a
    tapered fiber's ribbon narrows toward that end, as glsl/fibers/taper.glsl places it (ribbon.vert)."""
    guides = scene.segments[rows, 19].astype(np.uint32)
    return fiber_centers(lay, guides)[2].astype(np.float16).reshape(-1)


# --------------------------------------------------------------------------------------------------
# The renderer
# --------------------------------------------------------------------------------------------------
@dataclass
class BuildStats:
    fibers: int = 0                # fibers (guides x fibers per container)
    instances: int = 0             # (segment, fiber) ribbons
    gpu_bytes: int = 0
    seconds: float = 0.0           # generation + upload


class ExplicitRenderer:
    """The explicit (conventional) baseline: ``set_scene(scene, params)`` then ``render`` like ``Renderer``.

    ``budget_bytes`` caps the GPU buffers it may allocate; ``set_scene`` computes them first and raises
    ``ExplicitBudgetError`` (allocating nothing) above it.
    """

    def __init__(self, ctx: moderngl.Context, budget_bytes: int = DEFAULT_BUDGET_BYTES,
                 programs: ProgramCache | None = None, composite: str = "bins"):
        self.ctx = ctx
        if composite not in COMPOSITES:
            raise ValueError(f"composite {composite!r}: one of {', '.join(COMPOSITES)}")
        # how quality.filter = coverage composites a pixel's fragments (docs/antialias.md says why bins)
        self.composite = composite
        self.budget_bytes = int(budget_bytes)
        self.programs = programs or ProgramCache()
        self.scene: Scene | None = None
        self.plan: Plan | None = None
        self.stats = BuildStats()
        self._key: tuple | None = None
        self._warned: tuple[str, ...] = ()
        self._rows: moderngl.Buffer | None = None
        self._fibers: moderngl.Buffer | None = None
        self._colors: moderngl.Buffer | None = None     # the scene's per-guide colours (a groom file's)
        self._ends: moderngl.Buffer | None = None       # v_end per instance, only when fibers taper
        self._vaos: dict[int, moderngl.VertexArray] = {}
        self._targets: dict[tuple, moderngl.Framebuffer] = {}
        self._filter_fbos: dict[tuple, dict[str, moderngl.Framebuffer]] = {}
        # bound while targets are released: moderngl restores the previous binding after creating a
        # framebuffer, and rebinding a released one is an invalid operation
        self._parking: moderngl.Framebuffer | None = None

    # --- scene -------------------------------------------------------------------------------------
    def set_scene(self, scene: Scene, p: Params) -> BuildStats:
        """Generate every fiber of ``scene`` under ``p`` and upload it. Raises ExplicitBudgetError before
        allocating anything if the buffers would not fit the budget."""
        t0 = time.perf_counter()
        pl = plan(scene, p)
        if pl.gpu_bytes > self.budget_bytes:
            raise ExplicitBudgetError(pl.gpu_bytes, self.budget_bytes, pl.fibers, pl.bytes_per_fiber)
        if pl.instances > MAX_INSTANCES:
            raise ExplicitBudgetError(pl.gpu_bytes, MAX_INSTANCES * INSTANCE_BYTES, pl.fibers,
                                      pl.bytes_per_fiber)
        self.release()
        lay = fibers.ring_layout(p)
        self.scene, self.plan, self._key = scene, pl, _geometry_key(p)
        rows = scene.segments if pl.rows else np.zeros((1, scene.segments.shape[1]), np.float32)
        self._rows = self.ctx.buffer(np.ascontiguousarray(rows, np.float32).tobytes())
        self._fibers = self.ctx.buffer(reserve=max(1, pl.instances) * INSTANCE_BYTES)
        if pl.tapered:
            self._ends = self.ctx.buffer(reserve=max(1, pl.instances) * TAPER_BYTES)
        per_batch = max(1, GEN_INSTANCES // pl.fibers_per_container)
        for a in range(0, pl.rows, per_batch):
            rows_a = np.arange(a, min(pl.rows, a + per_batch))
            recs, _ = segment_fibers(scene, lay, rows_a)
            self._fibers.write(recs.tobytes(), offset=a * pl.fibers_per_container * INSTANCE_BYTES)
            if pl.tapered:
                self._ends.write(fiber_ends(scene, lay, rows_a).tobytes(),
                                 offset=a * pl.fibers_per_container * TAPER_BYTES)
        self.stats = BuildStats(pl.fibers, pl.instances, self.gpu_bytes, time.perf_counter() - t0)
        return self.stats

    def set_fibers(self, scene: Scene, records: np.ndarray, fibers_per_container: int,
                   fiber_radius: float) -> BuildStats:
        """Draw fibers made elsewhere (app/bench/strand_reference.py: child strands of a groom's own
        strands) through the same ribbons and shading: ``records`` holds ``fibers_per_container`` instance
        records (as ``segment_fibers`` makes them) per row of ``scene``, row-major. Until the next
        ``set_scene`` these fibers stay whatever fiber-layout parameters ``render`` is given; ids then
        report ring 0 and the fiber's index in its row."""
        F = int(fibers_per_container)
        records = np.ascontiguousarray(records, np.uint16).reshape(-1, 6)
        if F < 1 or len(records) != scene.n_segments * F:
            raise ValueError(f"set_fibers: {len(records):,} records for {scene.n_segments:,} rows x {F} fibers")
        pl = Plan(scene.n_segments, len(np.unique(scene.segments[:, 19])), F)
        if pl.gpu_bytes > self.budget_bytes:
            raise ExplicitBudgetError(pl.gpu_bytes, self.budget_bytes, pl.fibers, pl.bytes_per_fiber)
        t0 = time.perf_counter()
        self.release()
        self.scene, self.plan, self._key = scene, pl, ("fibers made elsewhere", float(fiber_radius))
        self._rows = self.ctx.buffer(np.ascontiguousarray(scene.segments, np.float32).tobytes())
        self._fibers = self.ctx.buffer(records.tobytes())
        self.stats = BuildStats(pl.fibers, pl.instances, self.gpu_bytes, time.perf_counter() - t0)
        return self.stats

    @property
    def gpu_bytes(self) -> int:
        """Bytes of GPU buffers holding the fibers and their segments (render targets not included)."""
        return sum(b.size for b in (self._rows, self._fibers, self._ends) if b is not None)

    def _bind_guide_colors(self, prog: moderngl.Program, p: Params) -> None:
        """The same per-guide colours as Renderer (glsl/shading/fiber_color.glsl, binding 4)."""
        colors = self.scene.guide_colors
        if colors is not None and self._colors is None:
            self._colors = self.ctx.buffer(self.scene.guide_color_rows().tobytes())
        (self._colors or self._rows).bind_to_storage_buffer(4)   # never read without file colours
        if "uGuideColors" in prog:
            prog["uGuideColors"].value = int(p["look.color_source"] == "file" and colors is not None)

    def release(self) -> None:
        """Free the fiber buffers (the renderer can take a new scene afterwards)."""
        for vao in self._vaos.values():
            vao.release()
        self._vaos.clear()
        for b in (self._rows, self._fibers, self._colors, self._ends):
            if b is not None:
                b.release()
        self._rows = self._fibers = self._colors = self._ends = None

    def release_targets(self) -> None:
        if not self._targets and not self._filter_fbos:
            return
        if self._parking is None:
            self._parking = self.ctx.framebuffer(self.ctx.renderbuffer((1, 1)))
        release_framebuffers(self._parking, self._targets)
        fbos = {(size, name): fbo for size, group in self._filter_fbos.items() for name, fbo in group.items()}
        release_framebuffers(self._parking, fbos)
        self._filter_fbos.clear()

    # --- drawing -----------------------------------------------------------------------------------
    def program(self, p: Params, filter_pass: int = 0) -> moderngl.Program:
        """The ribbon program: the opaque ribbons (``filter_pass`` 0), or one of the filtered passes (1
        nearest distance, 2 depth bins, 3 colour: ribbon.frag)."""
        defines = {"MAX_RINGS": MAX_RINGS, "SHADING_MODEL": SHADING_MODELS[p["look.model"]],
                   # a traced shadow needs the virtual traversal; the baseline keeps the density estimate
                   "SHADOW_MODE": 0 if p["look.self_shadow"] == "off" else 1,
                   # the ribbons narrow toward each fiber's tip only where set_scene stored the ends
                   "TAPER": int(self._ends is not None)}
        if filter_pass:
            defines.update(fibers.glsl_defines(), FILTER=filter_pass, COMPOSITE=COMPOSITES[self.composite])
        return self.programs.get(self.ctx, "explicit/ribbon.vert", "explicit/ribbon.frag", defines)

    def _vao(self, prog: moderngl.Program) -> moderngl.VertexArray:
        key = id(prog)
        if key not in self._vaos:
            F = self.plan.fibers_per_container
            vao = self.ctx.vertex_array(prog, [])
            # per segment row, advanced once every F instances; per (segment, fiber), every instance
            for name, cls, buf, fmt, offset, stride, divisor in (
                    ("aRowA", "f", self._rows, "4f", 0, ROW_BYTES, F),
                    ("aRowB", "f", self._rows, "4f", 16, ROW_BYTES, F),
                    ("aRowC", "f", self._rows, "4f", 32, ROW_BYTES, F),
                    ("aRowD", "f", self._rows, "4f", 48, ROW_BYTES, F),
                    ("aGuide", "f", self._rows, "1f", 76, ROW_BYTES, F),
                    ("aFiber", "f", self._fibers, "4f2", 0, INSTANCE_BYTES, 1),
                    ("aEnd", "f", self._fibers, "1f2", 8, INSTANCE_BYTES, 1),
                    ("aLook", "i", self._fibers, "1u2", 10, INSTANCE_BYTES, 1),
                    ("aFiberEnd", "f", self._ends, "1f2", 0, TAPER_BYTES, 1)):
                if name in prog and buf is not None:
                    vao.bind(prog[name].location, cls, buf, fmt, offset, stride, divisor)
            self._vaos[key] = vao
        return self._vaos[key]

    def _target(self, size: tuple[int, int]) -> moderngl.Framebuffer:
        if size not in self._targets:
            att = [self.ctx.texture(size, 4, dtype="f1"), self.ctx.texture(size, 4, dtype="u4"),
                   self.ctx.texture(size, 4, dtype="f4")]
            self._targets[size] = self.ctx.framebuffer(att, self.ctx.depth_renderbuffer(size))
        return self._targets[size]

    def _set_uniforms(self, prog: moderngl.Program, p: Params, cam: Camera, size, offset) -> None:
        lay = fibers.ring_layout(p)
        ring_first = np.zeros(MAX_RINGS, np.int32)
        ring_first[:lay.rings] = lay.first
        ring_radius = np.zeros(MAX_RINGS, np.float32)
        ring_radius[:lay.rings] = lay.ring_radius          # the clump profile's fiber radius by ring
        w, h = size
        th = np.tan(np.radians(cam.fov) / 2)
        clip = self._clip(cam, size, offset).astype(np.float32)
        values = {
            "uRings": lay.rings, "uFibersPerContainer": lay.fibers_per_container,
            "uFiberRadius": lay.fiber_radius,
            "uSceneFromCamera": tuple(self.scene.origin - cam.position),
            "uLightDir": tuple(light_direction(p)), "uLightIntensity": p["look.light_intensity"],
            "uAmbient": p["look.ambient"], "uRoughness": p["look.roughness"],
            "uTintVariation": p["look.tint_variation"], "uRoughnessVariation": p["look.roughness_variation"],
            "uTipWidth": p["strand.tip_width"], "uTaperStart": p["strand.taper_start"],
            # quality.filter = coverage: the virtual filter's footprint (renderer.py), the depth bins
            "uFootprint": p["quality.filter_width"] * 2.0 * th / h,
            "uBinWidth": BIN_RADII * self._median_radius(),
            "uNearest": 0, "uBins0": 1, "uBins1": 2, "uBins2": 3, "uBins3": 4,
            **_look_uniforms(p, lay.fibers_per_container),
        }
        if self._key[0] == "fibers made elsewhere":   # set_fibers: one "ring", the uploaded count and radius
            ring_first[:] = 0
            ring_radius[:] = self._key[1]
            values.update(uRings=1, uFibersPerContainer=self.plan.fibers_per_container, uFiberRadius=self._key[1])
        for name, value in values.items():
            if name in prog:
                prog[name].value = value
        if "uRingFirst" in prog:
            prog["uRingFirst"].write(ring_first[:prog["uRingFirst"].array_length].tobytes())
        if "uRingRadius" in prog:
            prog["uRingRadius"].write(ring_radius[:prog["uRingRadius"].array_length].tobytes())
        prog["uClipFromCamera"].write(clip.T.copy().tobytes())
        look.apply_lighting(prog, p, cam.position, cam.target)    # the key and the rig's other lights

    def _set_cutoff_uniforms(self, prog: moderngl.Program, p: Params, cam: Camera, size, offset) -> None:
        clip = self._clip(cam, size, offset)
        prog["uClipFromCamera"].write(clip.T.astype(np.float32).tobytes())
        prog["uCameraFromClip"].write(np.linalg.inv(clip).T.astype(np.float32).tobytes())
        prog["uSize"].value = (float(size[0]), float(size[1]))
        prog["uBinWidth"].value = BIN_RADII * self._median_radius()
        for i, name in enumerate(("uNearest", "uBins0", "uBins1", "uBins2", "uBins3")):
            prog[name].value = i

    @staticmethod
    def _clip(cam: Camera, size, offset) -> np.ndarray:
        """float64 projection * view rotation (camera at the origin), shifted by a sub-pixel ``offset``."""
        w, h = size
        clip = cam.clip_from_camera(w / h).astype(np.float64)
        # a sub-pixel ray offset moves the image the other way: shift NDC by -2 offset / size
        shift = np.identity(4)
        shift[0, 3], shift[1, 3] = -2.0 * offset[0] / w, -2.0 * offset[1] / h
        return shift @ clip

    def _median_radius(self) -> float:
        rows = self.scene.segments
        return float(np.median(rows[:, 3])) if len(rows) else 1.0

    def render(self, p: Params, cam: Camera, size: tuple[int, int], *, outputs=("color", "ids"),
               offset=(0.0, 0.0)) -> Frame:
        """Rasterize every fiber. ``outputs``: any of color, ids, geom (normal xyz, distance), draw (render,
        read nothing back: for timing, like the virtual renderer's). Fibers are
        regenerated first if a fiber-layout parameter changed since ``set_scene`` (the explicit method's
        price for a slider move; the virtual one only uploads uniforms).

        With quality.filter = coverage the colour is the filtered one (``_filtered_color``; ``coverage``
        then holds its alpha) and the ids, normal and depth stay the opaque ribbons' nearest fiber, drawn
        as without the filter (only when asked for)."""
        if self.scene is None:
            raise RuntimeError("ExplicitRenderer.render: call set_scene first")
        if _geometry_key(p) != self._key and self._key[0] != "fibers made elsewhere":
            self.set_scene(self.scene, p)
        ignored = ignored_shape(p)
        if ignored and ignored != self._warned:
            warnings.warn(f"the explicit baseline draws straight fibers: {', '.join(ignored)} not drawn "
                          f"(the virtual renderer draws them)", stacklevel=2)
        self._warned = ignored
        ctx = self.ctx
        size = (int(size[0]), int(size[1]))
        frame = Frame()
        filtered = p["quality.filter"] == "coverage"
        bg = np.asarray(p["look.background"])
        bg8 = np.round(np.clip(bg, 0, 1) ** (1 / 2.2) * 255).astype(np.uint8)
        if not filtered or {"ids", "geom"} & set(outputs):
            fbo = self._target(size)
            fbo.use()
            ctx.viewport = (0, 0) + size
            clear_targets(fbo)
            ctx.disable(moderngl.BLEND)
            ctx.disable(moderngl.CULL_FACE)
            ctx.enable(moderngl.DEPTH_TEST)
            ctx.depth_func = "<"
            frame.draws += self._draw(self.program(p), p, cam, size, offset)
            if "color" in outputs and not filtered:
                rgba = _read(fbo, 0, "f1", size)
                frame.color = np.where(rgba[..., 3:4] > 0, rgba[..., :3], bg8)
                frame.coverage = (rgba[..., 3] > 0).astype(np.float32)
            if "ids" in outputs:
                frame.ids = _read(fbo, 1, "u4", size)
            if "geom" in outputs:
                frame.geom = _read(fbo, 2, "f4", size)
        if filtered and ({"color", "draw"} & set(outputs)):
            color, coverage, draws = self._filtered_color(p, cam, size, offset, bg8, "color" in outputs)
            frame.draws += draws
            if "color" in outputs:
                frame.color, frame.coverage = color, coverage
        return frame

    def _draw(self, prog: moderngl.Program, p: Params, cam: Camera, size, offset) -> int:
        """One instanced draw of every ribbon with ``prog`` into the bound framebuffer; the draws made."""
        self._set_uniforms(prog, p, cam, size, offset)
        self._bind_guide_colors(prog, p)
        if not self.plan.instances:
            return 0
        # a tapered ribbon bends where its fiber starts to thin: two quads (ribbon.vert)
        strip = 6 if self._ends is not None else 4
        # the joint planes clip each ribbon (ribbon.vert: gl_ClipDistance 0 and 1)
        for plane in CLIP_PLANES:
            self.ctx.enable_direct(plane)
        try:
            self._vao(prog).render(moderngl.TRIANGLE_STRIP, vertices=strip, instances=self.plan.instances)
        finally:
            for plane in CLIP_PLANES:
                self.ctx.disable_direct(plane)
        return 1

    def _filter_targets(self, size) -> dict[str, moderngl.Framebuffer]:
        if size not in self._filter_fbos:
            tex = lambda: self.ctx.texture(size, 4, dtype="f4")     # noqa: E731
            nearest, bins, accum = [tex()], [tex() for _ in range(BINS // 4)], [tex(), tex()]
            for t in (*nearest, *bins):
                t.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self._filter_fbos[size] = {"nearest": self.ctx.framebuffer(nearest),
                                       "bins": self.ctx.framebuffer(bins),
                                       "accum": self.ctx.framebuffer(accum, self.ctx.depth_renderbuffer(size))}
        return self._filter_fbos[size]

    def _filtered_color(self, p: Params, cam: Camera, size, offset, bg8: np.ndarray, read: bool):
        """quality.filter = coverage: every ribbon widened by the footprint, its alpha the share of the
        footprint the fiber covers (ribbon.frag), composited per pixel without sorting: (1) the nearest
        fragment's distance, (2) optical depth in BINS depth bins behind it, (3) each fragment's colour
        weighted by its alpha and the transmittance in front of it read from the bins, and its optical
        depth. Alpha is 1 - exp(-optical depth); the colour, the weighted mean in linear light, goes over
        the background as the virtual filter's does (display levels, premultiplied). Returns (colour
        (H, W, 3) uint8 or None, alpha (H, W) float32 or None, draws)."""
        ctx = self.ctx
        t = self._filter_targets(size)
        ctx.viewport = (0, 0) + size
        ctx.disable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE)
        ctx.enable(moderngl.BLEND)
        ctx.blend_func = moderngl.ONE, moderngl.ONE
        draws = 0
        try:
            t["nearest"].use()
            t["nearest"].clear(1e30, 0.0, 0.0, 0.0)
            ctx.blend_equation = moderngl.MIN
            draws += self._draw(self.program(p, 1), p, cam, size, offset)
            ctx.blend_equation = moderngl.FUNC_ADD
            t["nearest"].color_attachments[0].use(0)
            if self.composite == "bins":
                t["bins"].use()
                t["bins"].clear(0.0, 0.0, 0.0, 0.0)
                draws += self._draw(self.program(p, 2), p, cam, size, offset)
                for i, b in enumerate(t["bins"].color_attachments):
                    b.use(1 + i)
            acc = t["accum"]
            acc.use()
            acc.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
            if self.composite == "bins":
                # each pixel's opaque distance into the depth buffer (cutoff.frag): the colour pass shades
                # only what lies in front of it
                cut = self.programs.get(ctx, "stages/fullscreen.vert", "explicit/cutoff.frag")
                self._set_cutoff_uniforms(cut, p, cam, size, offset)
                ctx.disable(moderngl.BLEND)
                ctx.enable(moderngl.DEPTH_TEST)
                ctx.depth_func = "1"
                acc.color_mask = ((False,) * 4,) * 2
                ctx.vertex_array(cut, []).render(vertices=3)
                acc.color_mask = ((True,) * 4,) * 2
                acc.depth_mask = False
                ctx.depth_func = "<"
                ctx.enable(moderngl.BLEND)
                draws += 1
            draws += self._draw(self.program(p, 3), p, cam, size, offset)
        finally:
            t["accum"].depth_mask = True
            ctx.depth_func = "<"
            ctx.blend_equation = moderngl.FUNC_ADD
            ctx.blend_func = moderngl.DEFAULT_BLENDING
            ctx.disable(moderngl.BLEND)
            ctx.enable(moderngl.DEPTH_TEST)
        if not read:
            return None, None, draws
        accum = _read(t["accum"], 0, "f4", size).astype(np.float64)
        if self.composite == "bins":        # every fragment's optical depth, those the cutoff skipped too
            depth = sum(_read(t["bins"], i, "f4", size).astype(np.float64).sum(-1) for i in range(BINS // 4))
        else:
            depth = _read(t["accum"], 1, "f4", size)[..., 0].astype(np.float64)
        alpha = 1.0 - np.exp(-depth)
        weight = accum[..., 3:4]
        linear = np.divide(accum[..., :3], weight, out=np.zeros_like(accum[..., :3]), where=weight > 0)
        shown = np.clip(linear, 0.0, 1.0) ** (1.0 / 2.2) * 255.0
        a = alpha[..., None]
        color = np.clip(np.round(shown * a + (1.0 - a) * bg8), 0, 255).astype(np.uint8)
        return color, alpha.astype(np.float32), draws


SHADING_MODELS = {"kajiya_kay": 0, "marschner": 1}
CLIP_PLANES = (0x3000, 0x3001)      # GL_CLIP_DISTANCE0, 1: a ribbon's root-side and tip-side joint planes


def _look_uniforms(p: Params, fibers_per_container: int) -> dict:
    """Colour, exposure and shadow inputs computed as the virtual renderer computes them (app/render/look.py
    where present: melanin colours, fiber density)."""
    try:
        from . import look
    except ImportError:  # an older checkout: RGB colour only, and the density the look module defines
        return {"uBaseColor": tuple(p["look.color"]), "uExposureScale": 2.0 ** p["look.exposure"],
                "uShadowDensity": p["look.shadow_density"],
                "uFiberDensity": fibers_per_container / np.pi * 2.0 * p["fibers.fiber_radius"]}
    return {"uBaseColor": look.base_color(p), "uTipColor": look.tip_color(p), "uTipBlend": p["look.tip_blend"],
            "uTipStart": p["look.tip_start"], "uExposureScale": 2.0 ** p["look.exposure"],
            "uShadowDensity": p["look.shadow_density"],
            "uFiberDensity": look.fiber_density(p, fibers_per_container)}


def _geometry_key(p: Params) -> tuple:
    # whether fibers taper decides whether their ends are stored; how much they taper is a uniform
    return (*(p[k] for k in GEOMETRY_KEYS), fibers.tapered(p))


def _read(fbo: moderngl.Framebuffer, attachment: int, dtype: str, size) -> np.ndarray:
    w, h = size
    np_dtype = {"f1": np.uint8, "u4": np.uint32, "f4": np.float32}[dtype]
    raw = fbo.read(viewport=(0, 0, w, h), components=4, attachment=attachment, dtype=dtype)
    return np.frombuffer(raw, np_dtype).reshape(h, w, 4)[::-1].copy()


def compare_frames(virtual: Frame, explicit: Frame) -> dict[str, float]:
    """How alike two frames of the same scene are, from their ids: ``coverage_agree`` is the fraction of
    all pixels where both show a fiber or both show background; ``covered_iou`` the pixels both cover over
    those either covers; ``id_agree`` the fraction of pixels both cover whose (guide, ring, fiber) match;
    with colour, ``color_diff`` is the mean absolute difference (0-255 per channel) where both cover."""
    hv, he = virtual.ids[..., 0] > 0, explicit.ids[..., 0] > 0
    either, both = hv | he, hv & he
    same_id = np.all(virtual.ids[..., :3] == explicit.ids[..., :3], -1) & both
    out = {
        "coverage_agree": float(np.mean(hv == he)),
        "covered_iou": float(both.sum() / max(1, either.sum())),
        "id_agree": float(same_id.sum() / max(1, both.sum())),
        "covered_virtual": float(hv.mean()),
        "covered_explicit": float(he.mean()),
    }
    if virtual.color is not None and explicit.color is not None and both.any():
        diff = np.abs(virtual.color.astype(np.int16) - explicit.color.astype(np.int16))
        out["color_diff"] = float(diff[both].mean())
    return out


def ignored_shape(p: Params) -> tuple[str, ...]:
    """Shape parameters set away from zero that the straight-fiber baseline does not draw."""
    return tuple(k for k in SHAPE_KEYS if p[k] != 0.0)


__all__ = ["DEFAULT_BUDGET_BYTES", "ExplicitBudgetError", "ExplicitRenderer", "Plan", "plan", "estimate_bytes",
           "fiber_centers", "fiber_key", "key_random", "segment_fibers", "compare_frames", "ignored_shape"]
