"""The camera: float64 on the CPU, camera-relative on the GPU.

The GPU never sees a world position. The renderer uploads the scene origin minus the camera position
(computed here in float64) and a projection that only rotates, so a scene 1e6 units from the world origin
renders exactly like the same scene at the origin.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pyrr

from ..params import Params
from ..scene.containers import Scene


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


@dataclass
class Camera:
    position: np.ndarray
    target: np.ndarray
    fov: float = 35.0                               # vertical, degrees
    near: float = 0.01
    far: float = 100.0
    up: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))

    def __post_init__(self):
        self.position = np.asarray(self.position, np.float64)
        self.target = np.asarray(self.target, np.float64)
        self.up = np.asarray(self.up, np.float64)

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(right, up, forward), orthonormal; stays defined when looking straight along ``up``."""
        forward = _unit(self.target - self.position)
        right = np.cross(forward, self.up)
        if np.linalg.norm(right) < 1e-9:
            right = np.cross(forward, [1.0, 0.0, 0.0] if abs(forward[0]) < 0.9 else [0.0, 1.0, 0.0])
        right = _unit(right)
        return right, np.cross(right, forward), forward

    def clip_from_camera(self, aspect: float) -> np.ndarray:
        """Projection times view rotation, for points relative to the camera (float32, column-major)."""
        right, up, forward = self.basis()
        view = np.identity(4)
        view[:3, :3] = np.stack([right, up, -forward])      # rows: camera axes
        proj = pyrr.matrix44.create_perspective_projection_matrix(self.fov, aspect, self.near, self.far).T
        return (proj @ view).astype(np.float32)

    def rays(self, width: int, height: int, offset=(0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
        """float64 ray origins and unit directions of every pixel centre, rows top to bottom, as the
        shader builds them (for the reference)."""
        right, up, forward = self.basis()
        th = math.tan(math.radians(self.fov) / 2)
        ys, xs = np.mgrid[0:height, 0:width].astype(np.float64)
        ys = height - 1 - ys                                # GL rows start at the bottom
        nx = (xs + 0.5 + offset[0]) / width * 2 - 1
        ny = (ys + 0.5 + offset[1]) / height * 2 - 1
        d = (forward[None] + (nx.reshape(-1, 1) * th * width / height) * right[None]
             + (ny.reshape(-1, 1) * th) * up[None])
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        return np.broadcast_to(self.position, d.shape).copy(), d

    @staticmethod
    def from_params(p: Params, scene: Scene, aspect: float = 16 / 9) -> Camera:
        """Orbit camera about the scene centre (plus ``camera.target``). Distance 0 frames the scene: the
        nearest distance at which all eight corners of its bounding box fit the view, plus a margin."""
        lo, hi = scene.bounds()
        centre = 0.5 * (lo + hi)
        radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-12)
        fov = p["camera.fov"]
        az, el = math.radians(p["camera.azimuth"]), math.radians(p["camera.elevation"])
        direction = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
        target = centre + np.asarray(p["camera.target"], np.float64)
        dist = p["camera.distance"] or _framing_distance(scene, target, direction, fov, aspect)
        near = p["camera.near"] or max(dist - 2.0 * radius, dist * 1e-4, 1e-9)
        far = p["camera.far"] or dist + 2.0 * radius
        if far <= near:
            far = near * 10
        return Camera(target + dist * direction, target, fov, near, far)


def _framing_distance(scene: Scene, target, direction, fov: float, aspect: float, margin: float = 1.06) -> float:
    """Smallest distance along ``direction`` from ``target`` at which every container end point (and its
    radius) fits the view: tighter than the bounding box, whose corners are often empty."""
    probe = Camera(target + direction, target, fov)
    right, up, forward = probe.basis()
    th = math.tan(math.radians(fov) / 2)
    pts, rad = scene.end_points()
    # one product for the three projections: this runs every orbit step of a 300k-point groom
    basis = np.stack([direction, right, up], axis=1)
    proj = pts @ basis - np.asarray(target, np.float64) @ basis
    toward = proj[:, 0] + rad                   # how far each point sits toward the camera
    lateral_x = (np.abs(proj[:, 1]) + rad) / (th * aspect)
    lateral_y = (np.abs(proj[:, 2]) + rad) / th
    need = np.maximum(lateral_x, lateral_y) * margin + toward
    extent = scene.end_point_extent()
    return float(max(need.max(), extent * 0.05, 1e-9))
