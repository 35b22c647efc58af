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
    """Rotate vector v by the smallest rotation taking unit a to unit b (parallel transport)."""
    c = float(np.dot(a, b))
    axis = np.cross(a, b)
    s = float(np.linalg.norm(axis))
    if s < 1e-12:
        if c > 0:
            return v
        # a 180 degree turn: any axis perpendicular to a works; pick one continuous with v
        axis = np.cross(a, v)
        n = np.linalg.norm(axis)
        axis = axis / n if n > 0 else orthonormal_x(a[None])[0]
        return 2 * np.dot(v, axis) * axis - v
    axis /= s
    # Rodrigues with cos = c, sin = s
    return v * c + np.cross(axis, v) * s + axis * np.dot(axis, v) * (1 - c)


@dataclass
class Scene:
    segments: np.ndarray                         # (N, SEGMENT_FLOATS) float32
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))  # float64 world position of the anchor
    name: str = "scene"
    n_guides: int = 0

    def __post_init__(self):
        self.segments = np.ascontiguousarray(self.segments, dtype=np.float32).reshape(-1, SEGMENT_FLOATS)
        self.origin = np.asarray(self.origin, dtype=np.float64).reshape(3)

    @property
    def n_segments(self) -> int:
        return len(self.segments)

    @property
    def nbytes(self) -> int:
        return int(self.segments.nbytes)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """World-space (float64) bounding box of all containers, radii included."""
        s = self.segments.astype(np.float64)
        r = np.maximum(s[:, 3], s[:, 7])[:, None]
        lo = np.minimum(s[:, 0:3], s[:, 4:7]) - r
        hi = np.maximum(s[:, 0:3], s[:, 4:7]) + r
        return lo.min(0) + self.origin, hi.max(0) + self.origin

    def translated(self, offset) -> "Scene":
        """The same scene moved in world space: only the float64 origin changes, never the float32 data."""
        return Scene(self.segments.copy(), self.origin + np.asarray(offset, np.float64), self.name, self.n_guides)

    @staticmethod
    def from_polylines(polylines: list[np.ndarray], radii, *, taper: float = 0.0, name: str = "scene",
                       origin=None) -> "Scene":
        """Containers from guide polylines (world units, float64).

        ``radii``: one root radius per guide, or a single number. The radius falls linearly with arc length
        to ``(1 - taper)`` of the root radius at the tip. Frames are parallel-transported from a robust root
        frame, joints are closed by bisecting (miter) planes, so fibers run on without a gap or a jump.
        """
        if len(polylines) > MAX_GUIDES:
            raise ValueError(f"{len(polylines)} guides: at most {MAX_GUIDES} are supported")
        radii = np.broadcast_to(np.asarray(radii, np.float64), (len(polylines),))
        pts_all = [np.asarray(p, np.float64) for p in polylines]
        if origin is None:
            stacked = np.concatenate(pts_all) if pts_all else np.zeros((1, 3))
            origin = 0.5 * (stacked.min(0) + stacked.max(0))
        origin = np.asarray(origin, np.float64)
        rows = []
        for g, pts in enumerate(pts_all):
            seglen = np.linalg.norm(np.diff(pts, axis=0), axis=1)
            keep = np.concatenate([[True], seglen > 0])
            pts = pts[keep]
            if len(pts) < 2:
                continue
            seglen = np.linalg.norm(np.diff(pts, axis=0), axis=1)
            v = np.concatenate([[0.0], np.cumsum(seglen)]) / seglen.sum()
            r = radii[g] * (1.0 - taper * v)
            axes = np.diff(pts, axis=0) / seglen[:, None]
            fx = orthonormal_x(axes[0])[0]
            for k in range(len(axes)):
                a = axes[k]
                if k > 0:
                    fx = _rotate_minimally(fx, axes[k - 1], a)
                    fx -= a * np.dot(fx, a)
                    fx /= np.linalg.norm(fx)
                n0 = a if k == 0 else _bisector(axes[k - 1], a)
                n1 = a if k == len(axes) - 1 else _bisector(a, axes[k + 1])
                rows.append(np.concatenate([pts[k] - origin, [r[k]], pts[k + 1] - origin, [r[k + 1]],
                                            n0, [v[k]], n1, [v[k + 1]], fx, [g]]))
        seg = np.array(rows, np.float64).reshape(-1, SEGMENT_FLOATS)
        return Scene(seg.astype(np.float32), origin, name, len(pts_all))


def _bisector(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Normal of the plane that splits the joint between directions a and b evenly."""
    n = a + b
    length = np.linalg.norm(n)
    if length < 1e-9:  # a full fold-back; the plane is perpendicular to the incoming axis
        return a
    return n / length
