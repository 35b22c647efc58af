"""Big renders in tiles, so a long render can say how far it is (and a 16K frame fits the targets).

A tile is rendered by the ordinary ``Renderer`` through a ``TileCamera``: the same eye, with a view
window cut out of the full image's, so every pixel gets the ray it would get in one big render (the
shader builds rays from forward + ndc.x * right + ndc.y * up; the proxy rectangles go through an
off-centre projection). The Python thread cannot report while the GPU call runs (moderngl holds the
GIL), so progress is reported between tiles.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..params import Params
from .camera import Camera
from .renderer import Frame, Renderer, _upscale

TILE = 1024                       # pixels a side: ~1 Mpix per draw, a few seconds at worst on llvmpipe
TILED_ABOVE_PIXELS = 4 * 2**20    # smaller frames render in one go


@dataclass
class TileCamera(Camera):
    """The part [x0, x0 + w) x [y0, y0 + h) (GL rows: y from the bottom) of a W x H view of ``full``."""

    full: Camera | None = None
    window: tuple[int, int, int, int, int, int] = (0, 0, 1, 1, 1, 1)   # x0, y0, w, h, W, H

    def _crop(self) -> tuple[float, float, float, float]:
        x0, y0, w, h, W, H = self.window
        sx, sy = w / W, h / H
        return sx, sy, (2 * x0 + w) / W - 1, (2 * y0 + h) / H - 1

    def basis(self):
        """Scaled so that the renderer's rays (forward + ndc.x * right * tan(fov/2) * w / h + ndc.y * up *
        tan(fov/2), tile ndc) are the full view's: right and up shrink by h / H, forward points at the
        tile's centre."""
        right, up, forward = self.full.basis()
        _, _, _, h, W, H = self.window
        _, _, cx, cy = self._crop()
        th = math.tan(math.radians(self.full.fov) / 2)
        k = h / H
        return right * k, up * k, forward + cx * th * (W / H) * right + cy * th * up

    def clip_from_camera(self, aspect: float) -> np.ndarray:
        """The full view's projection followed by the crop of its NDC square to the tile's."""
        _, _, _, _, W, H = self.window
        sx, sy, cx, cy = self._crop()
        crop = np.array([[1 / sx, 0, 0, -cx / sx], [0, 1 / sy, 0, -cy / sy], [0, 0, 1, 0], [0, 0, 0, 1]])
        return (crop @ self.full.clip_from_camera(W / H).astype(np.float64)).astype(np.float32)


def tile_camera(cam: Camera, window: tuple[int, int, int, int, int, int]) -> TileCamera:
    return TileCamera(cam.position, cam.target, cam.fov, cam.near, cam.far, cam.up, full=cam, window=window)


def tiles(size: tuple[int, int], tile: int = TILE) -> list[tuple[int, int, int, int]]:
    """(x0, y0, w, h) in GL pixels (rows from the bottom), row by row from the top of the picture."""
    W, H = size
    out = []
    for y1 in range(H, 0, -tile):
        y0 = max(0, y1 - tile)
        for x0 in range(0, W, tile):
            out.append((x0, y0, min(tile, W - x0), y1 - y0))
    return out


Progress = Callable[[int, int, float], None]     # (tiles done, tiles, seconds so far)


def render_tiled(renderer: Renderer, p: Params, cam: Camera, size: tuple[int, int], *, outputs=("color",),
                 tile: int = TILE, progress: Progress | None = None) -> Frame:
    """``Renderer.render_quality`` in tiles: the same picture, reported tile by tile."""
    scale = p["quality.render_scale"]
    W, H = (max(1, round(size[0] * scale)), max(1, round(size[1] * scale)))
    frame = Frame()
    parts = tiles((W, H), tile)
    t0 = time.perf_counter()
    for n, (x0, y0, w, h) in enumerate(parts):
        part = renderer.render(p, tile_camera(cam, (x0, y0, w, h, W, H)), (w, h), outputs=outputs)
        rows = slice(H - y0 - h, H - y0)             # arrays are top row first
        cols = slice(x0, x0 + w)
        for name in ("color", "coverage", "ids", "geom", "cost", "iters"):
            a = getattr(part, name)
            if a is None:
                continue
            if getattr(frame, name) is None:
                setattr(frame, name, np.zeros((H, W) + a.shape[2:], a.dtype))
            getattr(frame, name)[rows, cols] = a
        frame.draws += part.draws
        if progress is not None:
            progress(n + 1, len(parts), time.perf_counter() - t0)
    if (W, H) != tuple(size):
        frame = _upscale(frame, tuple(size))
    return frame


def print_progress(stream) -> Progress:
    """A one-line progress report on ``stream`` (a terminal gets it rewritten in place)."""
    tty = hasattr(stream, "isatty") and stream.isatty()

    def report(done: int, total: int, seconds: float) -> None:
        left = seconds / done * (total - done)
        text = f"rendering: tile {done}/{total}, {seconds:.0f} s, about {left:.0f} s left"
        if tty:
            stream.write("\r" + text + ("\n" if done == total else ""))
        else:
            stream.write(text + "\n")
        stream.flush()
    return report
