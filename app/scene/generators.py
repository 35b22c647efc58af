"""Scenes for tests and demos: containers only, built from generated guide polylines.

Every generator works in a Z-up world and returns a ``Scene`` via ``Scene.from_polylines``, so bent guides,
taper and frames are handled in one place.
"""

from __future__ import annotations

import math

import numpy as np

from ..params import Params
from .containers import Scene


def guide_polyline(root, up, length: float, segments: int, bend_deg: float, bend_dir=None) -> np.ndarray:
    """A guide that leaves ``root`` along ``up`` and bends by ``bend_deg`` in total, evenly per joint."""
    up = np.asarray(up, np.float64) / np.linalg.norm(up)
    if bend_dir is None:
        bend_dir = np.cross(up, [0.0, 0.0, 1.0]) if abs(up[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    side = np.asarray(bend_dir, np.float64)
    side = side - up * np.dot(side, up)
    side /= np.linalg.norm(side)
    pts = [np.asarray(root, np.float64)]
    per_joint = math.radians(bend_deg) / max(1, segments - 1) if segments > 1 else 0.0
    step = length / segments
    for k in range(segments):
        a = per_joint * k
        direction = up * math.cos(a) + side * math.sin(a)
        pts.append(pts[-1] + step * direction)
    return np.array(pts)


def poisson_disk(n: int, radius_min: float, extent: float, rng: np.random.Generator,
                 tries: int = 30) -> np.ndarray:
    """Up to n points in [-extent, extent]^2 no closer than radius_min (dart throwing on a grid).

    Blue-noise spacing keeps containers from overlapping almost completely, the drawback the thesis
    names for random placement (4.7).
    """
    cell = radius_min / math.sqrt(2)
    size = max(1, int(math.ceil(2 * extent / cell)))
    grid = -np.ones((size, size), np.int64)
    pts: list[np.ndarray] = []
    for _ in range(n * tries):
        if len(pts) >= n:
            break
        p = rng.uniform(-extent, extent, 2)
        gx, gy = (np.clip(((p + extent) / cell).astype(int), 0, size - 1))
        ok = True
        for ix in range(max(0, gx - 2), min(size, gx + 3)):
            for iy in range(max(0, gy - 2), min(size, gy + 3)):
                k = grid[ix, iy]
                if k >= 0 and np.sum((pts[k] - p) ** 2) < radius_min ** 2:
                    ok = False
                    break
            if not ok:
                break
        if ok:
            grid[gx, gy] = len(pts)
            pts.append(p)
    return np.array(pts).reshape(-1, 2)


def single(p: Params) -> Scene:
    guide = guide_polyline([0, 0, 0], [0, 0, 1], p["scene.length"], p["scene.segments"], p["scene.bend"])
    return Scene.from_polylines([guide], p["scene.radius"], taper=p["scene.taper"], name="single")


def carpet(p: Params) -> Scene:
    """Guides on a square patch of the z = 0 plane (thesis Figure 39)."""
    rng = np.random.default_rng(p["scene.seed"])
    n, r = p["scene.count"], p["scene.radius"]
    # area for n discs of radius ~1.6 r at ~60% packing
    extent = math.sqrt(n * math.pi * (1.6 * r) ** 2 / 0.6) / 2
    roots = poisson_disk(n, 1.6 * r, extent, rng)
    guides = []
    for xy in roots:
        tilt = rng.normal(0, 0.08, 2)
        up = np.array([tilt[0], tilt[1], 1.0])
        bend_dir = np.array([1.0, 0.3, 0.0]) + np.append(rng.normal(0, 0.2, 2), 0)
        guides.append(guide_polyline([xy[0], xy[1], 0.0], up, p["scene.length"], p["scene.segments"],
                                     p["scene.bend"], bend_dir))
    return Scene.from_polylines(guides, r, taper=p["scene.taper"], name="carpet")


def fibonacci_sphere(n: int) -> np.ndarray:
    k = np.arange(n) + 0.5
    z = 1 - 2 * k / n
    phi = math.pi * (3 - math.sqrt(5)) * k
    s = np.sqrt(1 - z * z)
    return np.stack([s * np.cos(phi), s * np.sin(phi), z], axis=1)


def furball(p: Params) -> Scene:
    """Short fur on a sphere: guides along the normals of an evenly covered sphere."""
    n, r = p["scene.count"], p["scene.radius"]
    # sphere big enough that neighbouring roots sit ~2 radii apart
    sphere = max(p["scene.length"], math.sqrt(n * (2.0 * r) ** 2 / (4 * math.pi)))
    normals = fibonacci_sphere(n)
    rng = np.random.default_rng(p["scene.seed"])
    # bend each guide toward its own random side: one shared direction would comb a parting and a whorl
    sides = rng.normal(size=(n, 3))
    guides = [guide_polyline(nrm * sphere, nrm, p["scene.length"], p["scene.segments"], p["scene.bend"], side)
              for nrm, side in zip(normals, sides)]
    return Scene.from_polylines(guides, r, taper=p["scene.taper"], name="furball")


def curved(p: Params) -> Scene:
    """Guides on a curved (saddle-and-wave) surface, along its normals: every container has its own
    frame (thesis 4.2 asks for a curved surface to exercise the local frame)."""
    rng = np.random.default_rng(p["scene.seed"])
    n, r = p["scene.count"], p["scene.radius"]
    extent = math.sqrt(n * math.pi * (1.6 * r) ** 2 / 0.6) / 2
    roots = poisson_disk(n, 1.6 * r, extent, rng)
    amp, k = 0.35 * extent, math.pi / max(extent, 1e-12)
    guides = []
    for x, y in roots:
        z = amp * math.sin(k * x) * math.cos(0.5 * k * y)
        dzdx = amp * k * math.cos(k * x) * math.cos(0.5 * k * y)
        dzdy = -amp * 0.5 * k * math.sin(k * x) * math.sin(0.5 * k * y)
        normal = np.array([-dzdx, -dzdy, 1.0])
        guides.append(guide_polyline([x, y, z], normal, p["scene.length"], p["scene.segments"], p["scene.bend"]))
    return Scene.from_polylines(guides, r, taper=p["scene.taper"], name="curved")


GENERATORS = {"single": single, "carpet": carpet, "furball": furball, "curved": curved}


def build_scene(p: Params) -> Scene:
    """The scene the parameters describe (generator or groom file)."""
    name = p["scene.generator"]
    if name == "groom":
        from .grooms import scene_from_groom  # lazy: only groom scenes need the loaders
        return scene_from_groom(p)
    return GENERATORS[name](p)
