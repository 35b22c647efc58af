"""The scene: container segments (hair cylinders around guide hairs) and nothing per fiber.

A guide hair is a polyline; each of its segments becomes one container segment. Segments are stored as one
float32 array of ``SEGMENT_FLOATS`` numbers each, uploaded once as a per-instance vertex buffer:

    0-2  p0   root-side end point (relative to ``Scene.origin``)     3  r0  radius at p0
    4-6  p1   tip-side end point                                     7  r1  radius at p1
    8-10 n0   joint (miter) plane normal at p0, pointing into the segment      11 v0  guide parameter at p0
    12-14 n1  joint (miter) plane normal at p1, pointing out of the segment    15 v1  guide parameter at p1
    16-18 fx  the segment's frame x axis (unit, perpendicular to the axis)     19 guide index

``v`` runs from 0 at the root to 1 at the tip of the guide (arc length fraction), so fiber length
randomization and fiber identity span the whole guide. Positions are stored relative to a float64 origin
(the scene centre) so that a scene far from the world origin keeps its float32 precision; the renderer adds
the camera offset, computed in float64, as a uniform.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

SEGMENT_FLOATS = 20
SEGMENT_BYTES = SEGMENT_FLOATS * 4
MAX_GUIDES = 1 << 24  # the guide index travels as a float32; integers above 2^24 are not exact
_ROW_CHUNK = 1 << 16  # guides turned into container rows per vectorised step: bounds the float64 scratch


# Every tangent frame field on the sphere has a singular direction (the hairy ball theorem). Frisvad's
# basis puts it at -Z, and Duff et al.'s branchless fix jumps across the whole equator (z = 0), which is
# where a guide along X lives. We use Frisvad's basis in a rotated space whose singular direction is
# SINGULAR_AXIS: a direction far from +-X, +-Y, +-Z and their diagonals, so axis-aligned and nearly
# axis-aligned guides get a frame that is smooth (no pattern jump) and well conditioned.
SINGULAR_AXIS = np.array([-0.31, 0.53, -0.79]) / np.linalg.norm([-0.31, 0.53, -0.79])


def _rotation_to_minus_z(q: np.ndarray) -> np.ndarray:
    target = np.array([0.0, 0.0, -1.0])
    v = np.cross(q, target)
    c = float(np.dot(q, target))
    k = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.identity(3) + k + k @ k / (1.0 + c)


_TO_SINGULAR = _rotation_to_minus_z(SINGULAR_AXIS)


def orthonormal_x(z: np.ndarray) -> np.ndarray:
    """A unit vector perpendicular to each unit ``z`` (N,3), smooth everywhere but at ``SINGULAR_AXIS``
    itself (see above); within an angle a of it, a tilt d turns the vector by at most about 2 d / a."""
    z = np.atleast_2d(np.asarray(z, np.float64))
    zr = z @ _TO_SINGULAR.T                       # rotated so the singular direction is -Z
    # 1 + z cancels near the singular direction; there 1 + z = (x^2 + y^2) / (1 - z) keeps every digit,
    # so the basis turns smoothly (by twice the azimuth, as a field must about its singular point) all
    # the way in, instead of switching to a fixed vector at some distance and jumping across that circle
    xy2 = zr[:, 0] ** 2 + zr[:, 1] ** 2
    one_plus = np.where(zr[:, 2] < 0.0, xy2 / np.maximum(1.0 - zr[:, 2], 1.0), 1.0 + zr[:, 2])
    near = one_plus <= 0.0                        # the singular direction itself: any perpendicular
    safe = np.where(near, 1.0, one_plus)
    x = np.stack([1.0 - zr[:, 0] ** 2 / safe, -zr[:, 0] * zr[:, 1] / safe, -zr[:, 0]], axis=1)
    x = np.where(near[:, None], np.array([1.0, 0.0, 0.0]), x)
    x = x @ _TO_SINGULAR                          # back to world space
    x -= z * (x * z).sum(1, keepdims=True)
    return x / np.linalg.norm(x, axis=1, keepdims=True)


def _rotate_minimally(v: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotate each row of v (S, 3) by the smallest rotation taking unit a to unit b (parallel transport)."""
    c = (a * b).sum(axis=1, keepdims=True)
    axis = np.cross(a, b)
    s = np.linalg.norm(axis, axis=1, keepdims=True)
    turned = s[:, 0] >= 1e-12
    out = v.copy()
    if turned.any():
        # Rodrigues with cos = c, sin = s
        ax = axis[turned] / s[turned]
        vt, ct, st = v[turned], c[turned], s[turned]
        out[turned] = vt * ct + np.cross(ax, vt) * st + ax * (ax * vt).sum(axis=1, keepdims=True) * (1 - ct)
    back = ~turned & (c[:, 0] <= 0)
    if back.any():
        # A 180 degree turn: mirror about an axis perpendicular to a, continuous with v where possible.
        ax = np.cross(a[back], v[back])
        n = np.linalg.norm(ax, axis=1, keepdims=True)
        fallback = orthonormal_x(a[back])
        ax = np.where(n > 0, ax / np.where(n > 0, n, 1.0), fallback)
        out[back] = 2 * (v[back] * ax).sum(axis=1, keepdims=True) * ax - v[back]
    return out


def _bisector(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Normal of the plane that splits each joint between rows of directions a and b (S, 3) evenly; a full
    fold-back gets the plane perpendicular to the incoming axis."""
    n = a + b
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.where(length < 1e-9, a, n / np.where(length < 1e-9, 1.0, length))


def container_rows(guides: np.ndarray, radii: np.ndarray, taper: float, origin: np.ndarray) -> np.ndarray:
    """Container rows of S guides of equal point count at once: (S * (M - 1), SEGMENT_FLOATS) float64, guide
    after guide, guide index 0 .. S - 1.

    ``guides`` is (S, M, 3) float64 with no zero-length piece (``Scene.from_polylines`` drops those points
    first). The radius falls linearly with arc length to ``(1 - taper)`` of the root radius at the tip;
    frames are parallel-transported from a robust root frame; joints are closed by bisecting (miter) planes,
    so fibers run on without a gap or a jump. Vectorised across guides: a per-segment Python loop took 12 s
    for harolongo's 63k segments, this takes a few hundredths.
    """
    S, M = guides.shape[:2]
    seglen = np.linalg.norm(np.diff(guides, axis=1), axis=2)                  # (S, M-1)
    v = np.concatenate([np.zeros((S, 1)), np.cumsum(seglen, axis=1)], axis=1) / seglen.sum(axis=1)[:, None]
    r = np.asarray(radii, np.float64)[:, None] * (1.0 - taper * v)            # (S, M)
    axes = np.diff(guides, axis=1) / seglen[:, :, None]                      # (S, M-1, 3)
    rows = np.empty((S, M - 1, SEGMENT_FLOATS))
    fx = orthonormal_x(axes[:, 0])
    for k in range(M - 1):
        a = axes[:, k]
        if k > 0:
            fx = _rotate_minimally(fx, axes[:, k - 1], a)
            fx -= a * (fx * a).sum(axis=1, keepdims=True)
            fx /= np.linalg.norm(fx, axis=1, keepdims=True)
        rows[:, k, 0:3] = guides[:, k] - origin
        rows[:, k, 3] = r[:, k]
        rows[:, k, 4:7] = guides[:, k + 1] - origin
        rows[:, k, 7] = r[:, k + 1]
        rows[:, k, 8:11] = a if k == 0 else _bisector(axes[:, k - 1], a)
        rows[:, k, 11] = v[:, k]
        rows[:, k, 12:15] = a if k == M - 2 else _bisector(a, axes[:, k + 1])
        rows[:, k, 15] = v[:, k + 1]
        rows[:, k, 16:19] = fx
        rows[:, k, 19] = np.arange(S)
    return rows.reshape(-1, SEGMENT_FLOATS)


def _packed(polylines) -> tuple[np.ndarray, np.ndarray]:
    """All points of the polylines as one (N, 3) float64 array and the point count of each polyline."""
    if isinstance(polylines, np.ndarray) and polylines.ndim == 3:
        return np.asarray(polylines, np.float64).reshape(-1, 3), np.full(len(polylines), polylines.shape[1])
    arrays = [np.asarray(q, np.float64).reshape(-1, 3) for q in polylines]
    counts = np.fromiter((len(q) for q in arrays), np.int64, len(arrays))
    return (np.concatenate(arrays) if arrays else np.zeros((0, 3))), counts


GUIDE_COLOR_FLOATS = 8  # per guide: root rgb, 0, tip rgb, 0 (two std430 vec4: glsl/shading/fiber_color.glsl)


def joint_slope(cos_tilt: np.ndarray) -> np.ndarray:
    """How far a joint plane leans past its end point per unit of radius (tan of its tilt), from the cosine
    between the plane's normal and the segment axis: the numpy face of container.glsl's joint_slope, for
    the bounds the renderer, the hierarchy and the Blender export put around each container."""
    c = np.abs(cos_tilt)
    return np.sqrt(np.maximum(0.0, 1.0 - c * c)) / np.maximum(c, 1e-6)


@dataclass
class Scene:
    segments: np.ndarray                         # (N, SEGMENT_FLOATS) float32
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))  # float64 world position of the anchor
    name: str = "scene"
    n_guides: int = 0
    # Per guide, never per fiber: the groom file's linear colour at the guide's root and tip, (n_guides, 2, 3)
    # float32, or None where the source has no colours (generators, most groom files).
    guide_colors: np.ndarray | None = None
    # Derived once and kept: a scene's rows are uploaded to the GPU once and never changed in place, and the
    # viewer asks for its bounds and end points several times a UI frame (harolongo: ~50 ms each).
    _derived: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self):
        self.segments = np.ascontiguousarray(self.segments, dtype=np.float32).reshape(-1, SEGMENT_FLOATS)
        self.origin = np.asarray(self.origin, dtype=np.float64).reshape(3)
        if self.guide_colors is not None:
            colors = np.ascontiguousarray(self.guide_colors, dtype=np.float32)
            guides = int(self.segments[:, 19].max()) + 1 if len(self.segments) else 0
            if colors.ndim != 3 or colors.shape[1:] != (2, 3) or len(colors) < guides:
                raise ValueError(f"guide_colors must be (guides, 2, 3) for {guides} guides, not {colors.shape}")
            if not np.isfinite(colors).all():
                raise ValueError("guide_colors holds a non-finite value")
            self.guide_colors = np.clip(colors, 0.0, 1.0)

    @property
    def n_segments(self) -> int:
        return len(self.segments)

    @property
    def nbytes(self) -> int:
        return int(self.segments.nbytes) + self.guide_color_bytes

    @property
    def guide_color_bytes(self) -> int:
        """Bytes of the per-guide colour buffer on the GPU (0 without file colours)."""
        return 0 if self.guide_colors is None else len(self.guide_colors) * GUIDE_COLOR_FLOATS * 4

    def guide_color_rows(self) -> np.ndarray:
        """The per-guide colours as the shader reads them: (guides, GUIDE_COLOR_FLOATS) float32."""
        out = np.zeros((0 if self.guide_colors is None else len(self.guide_colors), 2, 4), np.float32)
        if self.guide_colors is not None:
            out[:, :, :3] = self.guide_colors
        return out.reshape(-1, GUIDE_COLOR_FLOATS)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """World-space (float64) bounding box of all containers, radii included."""
        if "bounds" not in self._derived:
            s = self.segments.astype(np.float64)
            r = np.maximum(s[:, 3], s[:, 7])[:, None]
            lo = np.minimum(s[:, 0:3], s[:, 4:7]) - r
            hi = np.maximum(s[:, 0:3], s[:, 4:7]) + r
            self._derived["bounds"] = (lo.min(0) + self.origin, hi.max(0) + self.origin)
        lo, hi = self._derived["bounds"]
        return lo.copy(), hi.copy()

    def end_points(self) -> tuple[np.ndarray, np.ndarray]:
        """Every segment's two end points in world space (float64, (2N, 3)) and their radii ((2N,)), root ends
        first. Read-only arrays, computed once: the camera frames the scene from them."""
        if "end_points" not in self._derived:
            seg = self.segments
            pts = np.concatenate([seg[:, 0:3], seg[:, 4:7]]).astype(np.float64) + self.origin
            rad = np.concatenate([seg[:, 3], seg[:, 7]]).astype(np.float64)
            pts.flags.writeable = rad.flags.writeable = False
            self._derived["end_points"] = (pts, rad)
        return self._derived["end_points"]

    def end_point_extent(self) -> float:
        """The diagonal of the end points' box plus the widest end's diameter (computed once)."""
        if "extent" not in self._derived:
            pts, rad = self.end_points()
            self._derived["extent"] = float(np.linalg.norm(pts.max(0) - pts.min(0))) + 2 * float(rad.max())
        return self._derived["extent"]

    def translated(self, offset) -> Scene:
        """The same scene moved in world space: only the float64 origin changes, never the float32 data."""
        return Scene(self.segments.copy(), self.origin + np.asarray(offset, np.float64), self.name, self.n_guides,
                     None if self.guide_colors is None else self.guide_colors.copy())

    @staticmethod
    def from_polylines(polylines: list[np.ndarray], radii, *, taper: float = 0.0, name: str = "scene",
                       origin=None) -> Scene:
        """Containers from guide polylines (world units, float64).

        ``radii``: one root radius per guide, or a single number. The radius falls linearly with arc length
        to ``(1 - taper)`` of the root radius at the tip. Frames are parallel-transported from a robust root
        frame, joints are closed by bisecting (miter) planes, so fibers run on without a gap or a jump.
        """
        if len(polylines) > MAX_GUIDES:
            raise ValueError(f"{len(polylines)} guides: at most {MAX_GUIDES} are supported")
        radii = np.broadcast_to(np.asarray(radii, np.float64), (len(polylines),))
        pts, counts = _packed(polylines)
        if origin is None:
            stacked = pts if len(pts) else np.zeros((1, 3))
            origin = 0.5 * (stacked.min(0) + stacked.max(0))
        origin = np.asarray(origin, np.float64)
        # A point that repeats the one before it makes no container: drop it, so a guide may end up shorter
        # (or, under two points, with no container at all) but never has a zero-length piece.
        ends = np.cumsum(counts)
        starts = ends - counts
        keep = np.ones(len(pts), bool)
        keep[1:] = np.linalg.norm(np.diff(pts, axis=0), axis=1) > 0
        keep[starts[counts > 0]] = True
        kept = np.add.reduceat(keep.astype(np.int64), starts[counts > 0]) if len(pts) else 0
        kcounts = np.zeros(len(counts), np.int64)
        kcounts[counts > 0] = kept
        kpts = pts[keep]
        kstarts = np.cumsum(kcounts) - kcounts
        nrows = np.where(kcounts >= 2, kcounts - 1, 0)
        rstarts = np.cumsum(nrows) - nrows
        seg = np.empty((int(nrows.sum()), SEGMENT_FLOATS), np.float32)
        # One vectorised pass per point count (generators and resampled grooms have one), guides in order.
        for m in np.unique(kcounts[kcounts >= 2]):
            group = np.flatnonzero(kcounts == m)
            for c in range(0, len(group), _ROW_CHUNK):
                g = group[c:c + _ROW_CHUNK]
                guides = kpts[kstarts[g][:, None] + np.arange(m)]
                rows = container_rows(guides, radii[g], taper, origin)
                rows[:, 19] = np.repeat(g, m - 1)
                seg[(rstarts[g][:, None] + np.arange(m - 1)).ravel()] = rows
        return Scene(seg, origin, name, len(polylines))
