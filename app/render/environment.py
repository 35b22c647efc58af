"""Environment light from a lat-long HDR image: loading (.exr, .hdr), two generated ones, and its
reduction to a few directional lights that the hair shading models can take.

Hair is lit by the whole sky, but each virtual fiber is shaded by a closed-form model (Kajiya-Kay or
Marschner) per light. So the map is cut into ``ENV_LIGHTS`` regions of equal energy (median cut,
Debevec 2005): each region becomes one directional light at its energy centroid carrying the region's
radiance times solid angle. The lights sum to the map's total, so brightness and colour follow the
image and bright parts (a window, a sun) keep their own highlights; the cost per pixel is
``ENV_LIGHTS`` evaluations of the model, whatever the image size.

Lat-long convention as Blender's equirectangular environment texture (so the export can hand Cycles the
same file): the centre column looks along +X, azimuth phi = 2 pi (0.5 - u) about +Z, the top row is up.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import VfiberError

ENV_LIGHTS = 8
GENERATED = ("studio", "sky")


class EnvironmentError_(VfiberError, ValueError):
    """An environment image that cannot be used; the message names the file."""


@dataclass(frozen=True)
class DirectionalLight:
    direction: tuple[float, float, float]      # toward the light, world (+Z up)
    color: tuple[float, float, float]          # linear RGB intensity


def lat_long_directions(h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit directions (h, w, 3) of pixel centres and each pixel's solid angle (h, w)."""
    v = (np.arange(h) + 0.5) / h
    u = (np.arange(w) + 0.5) / w
    theta = v * math.pi                                   # from +Z
    phi = 2 * math.pi * (0.5 - u)
    st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
    d = np.stack([st * np.cos(phi)[None], st * np.sin(phi)[None], np.broadcast_to(ct, (h, w))], axis=-1)
    solid = (2 * math.pi / w) * (math.pi / h) * np.broadcast_to(st, (h, w))
    return d, solid


def generated(name: str, h: int = 64, w: int = 128) -> np.ndarray:
    """Small procedural lat-long maps (linear RGB, float32), so environment light works with no file."""
    d, _ = lat_long_directions(h, w)
    z = d[..., 2:3]
    if name == "studio":
        # grey cyclorama, a large warm soft box front-left and a cool strip light behind
        img = 0.18 * np.clip(0.6 + 0.4 * z, 0.2, 1.0) * np.ones(3)
        def box(az, el, size, color):
            a = np.radians(az), np.radians(el)
            c = np.array([math.cos(a[1]) * math.cos(a[0]), math.cos(a[1]) * math.sin(a[0]), math.sin(a[1])])
            return np.exp((d @ c - 1.0) / size)[..., None] * np.asarray(color)
        img = img + box(40, 35, 0.02, (9.0, 7.5, 6.0)) + box(200, 20, 0.01, (3.0, 4.0, 6.0))
    elif name == "sky":
        sky = np.array([0.25, 0.45, 0.9]) * np.clip(z, 0, 1) ** 0.5 + np.array([0.7, 0.75, 0.8]) * (1 - np.abs(z)) ** 4
        ground = np.array([0.12, 0.1, 0.08]) * np.ones(3)
        img = np.where(z > 0, sky, ground)
        sun = np.array([math.cos(0.7) * math.cos(2.2), math.cos(0.7) * math.sin(2.2), math.sin(0.7)])
        img = img + np.exp((d @ sun - 1.0) / 0.0015)[..., None] * np.array([60.0, 52.0, 40.0])
    else:
        raise EnvironmentError_(f"no generated environment {name!r}: one of {', '.join(GENERATED)}")
    return img.astype(np.float32)


def read_image(path: str | Path) -> np.ndarray:
    """A lat-long image as (h, w, 3) float32 linear RGB: OpenEXR (.exr) or Radiance RGBE (.hdr)."""
    path = Path(path)
    if not path.is_file():
        raise EnvironmentError_(f"{path}: no such environment image")
    suffix = path.suffix.lower()
    try:
        if suffix == ".exr":
            import OpenEXR

            with OpenEXR.File(str(path)) as f:
                channels = f.channels()
                if "RGB" in channels:
                    img = channels["RGB"].pixels
                elif "RGBA" in channels:
                    img = channels["RGBA"].pixels[..., :3]
                else:
                    img = np.stack([channels[c].pixels for c in ("R", "G", "B")], axis=-1)
            img = np.asarray(img, np.float32)
        elif suffix == ".hdr":
            img = read_hdr(path.read_bytes())
        else:
            raise EnvironmentError_(f"{path}: environment images are .exr or .hdr (lat-long)")
    except EnvironmentError_:
        raise
    except Exception as e:  # a truncated or foreign file: one line naming it
        raise EnvironmentError_(f"{path}: not a readable {suffix} image ({e})") from None
    if img.ndim != 3 or img.shape[0] < 2 or img.shape[1] < 2:
        raise EnvironmentError_(f"{path}: expected a colour image, got shape {img.shape}")
    if not np.isfinite(img).all():
        img = np.nan_to_num(img, nan=0.0, posinf=0.0, neginf=0.0)
    return np.maximum(img, 0.0)


def read_hdr(data: bytes) -> np.ndarray:
    """Radiance RGBE (flat or run-length encoded scanlines), '-Y h +X w' orientation."""
    end = data.index(b"\n\n") + 2
    header = data[:end].decode("ascii", "replace")
    if not header.startswith(("#?RADIANCE", "#?RGBE")) or "32-bit_rle_rgbe" not in header:
        raise ValueError("not a Radiance RGBE file")
    line_end = data.index(b"\n", end)
    dims = data[end:line_end].decode().split()
    if len(dims) != 4 or dims[0] != "-Y" or dims[2] != "+X":
        raise ValueError(f"unsupported orientation {' '.join(dims)}")
    h, w = int(dims[1]), int(dims[3])
    buf = np.frombuffer(data, np.uint8, offset=line_end + 1)
    out = np.zeros((h, w, 4), np.uint8)
    pos = 0
    for y in range(h):
        if w >= 8 and w < 32768 and buf[pos] == 2 and buf[pos + 1] == 2 and (buf[pos + 2] << 8 | buf[pos + 3]) == w:
            pos += 4
            for c in range(4):                   # each channel run-length encoded on its own
                x = 0
                while x < w:
                    n = int(buf[pos])
                    pos += 1
                    if n > 128:
                        out[y, x:x + n - 128, c] = buf[pos]
                        x += n - 128
                        pos += 1
                    else:
                        out[y, x:x + n, c] = buf[pos:pos + n]
                        x += n
                        pos += n
        else:
            out[y] = buf[pos:pos + 4 * w].reshape(w, 4)
            pos += 4 * w
    e = out[..., 3].astype(np.int32)
    scale = np.where(e > 0, np.ldexp(1.0, e - 136), 0.0)
    return (out[..., :3] * scale[..., None]).astype(np.float32)


def write_hdr(path: str | Path, img: np.ndarray) -> None:
    """Flat (unencoded) Radiance RGBE: enough to hand a generated map to another program."""
    img = np.maximum(np.asarray(img, np.float64), 0.0)
    h, w = img.shape[:2]
    top = img.max(axis=-1)
    mant, exp = np.frexp(top)
    scale = np.where(top > 1e-32, mant * 256.0 / np.maximum(top, 1e-32), 0.0)
    rgbe = np.zeros((h, w, 4), np.uint8)
    rgbe[..., :3] = np.clip(img * scale[..., None], 0, 255).astype(np.uint8)
    rgbe[..., 3] = np.where(top > 1e-32, exp + 128, 0).astype(np.uint8)
    head = f"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {h} +X {w}\n".encode()
    Path(path).write_bytes(head + rgbe.tobytes())


def median_cut(img: np.ndarray, count: int = ENV_LIGHTS) -> list[DirectionalLight]:
    """``count`` (a power of two) directional lights of equal energy that sum to the map's radiance x
    solid angle. Splits each region across its longer side (in solid-angle terms) at its energy median."""
    h, w = img.shape[:2]
    d, solid = lat_long_directions(h, w)
    flux = img[..., :3].astype(np.float64) * solid[..., None]          # radiance x solid angle per pixel
    energy = flux @ np.array([0.2126, 0.7152, 0.0722])
    regions = [(0, h, 0, w)]
    while len(regions) < count:
        nxt = []
        for (y0, y1, x0, x1) in regions:
            if y1 - y0 < 2 and x1 - x0 < 2:
                nxt.append((y0, y1, x0, x1))
                continue
            rows = np.sin((np.arange(y0, y1) + 0.5) / h * math.pi).mean()
            wide = (x1 - x0) * rows * 2 >= (y1 - y0) and x1 - x0 >= 2 or y1 - y0 < 2
            e = energy[y0:y1, x0:x1]
            axis_sum = e.sum(axis=0) if wide else e.sum(axis=1)
            c = np.cumsum(axis_sum)
            cut = int(np.searchsorted(c, c[-1] / 2)) + 1 if c[-1] > 0 else len(c) // 2
            cut = min(max(cut, 1), len(c) - 1)
            if wide:
                nxt += [(y0, y1, x0, x0 + cut), (y0, y1, x0 + cut, x1)]
            else:
                nxt += [(y0, y0 + cut, x0, x1), (y0 + cut, y1, x0, x1)]
        if len(nxt) == len(regions):
            break
        regions = nxt
    lights = []
    for (y0, y1, x0, x1) in regions:
        f = flux[y0:y1, x0:x1].reshape(-1, 3)
        e = energy[y0:y1, x0:x1].reshape(-1)
        dirs = d[y0:y1, x0:x1].reshape(-1, 3)
        weights = e if e.sum() > 0 else solid[y0:y1, x0:x1].reshape(-1)
        c = (dirs * weights[:, None]).sum(axis=0)
        c = c / np.linalg.norm(c) if np.linalg.norm(c) > 1e-12 else dirs.mean(axis=0)
        lights.append(DirectionalLight(tuple(float(x) for x in c), tuple(float(x) for x in f.sum(axis=0))))
    return lights


def environment_lights(source: str, count: int = ENV_LIGHTS) -> tuple[DirectionalLight, ...]:
    """The median-cut lights of a generated map's name or an image path (cached by the file's size and
    time: a slider drag on the rotation or intensity does not reload it; saving a new image does)."""
    stamp = None
    if source not in GENERATED:
        try:
            st = Path(source).stat()
            stamp = (st.st_mtime_ns, st.st_size)
        except OSError:
            pass                       # read_image says what is wrong with it
    return _environment_lights(source, count, stamp)


@functools.lru_cache(maxsize=8)
def _environment_lights(source: str, count: int, stamp) -> tuple[DirectionalLight, ...]:
    img = generated(source) if source in GENERATED else read_image(source)
    return tuple(median_cut(img, count))


def environment_image(source: str) -> np.ndarray:
    return generated(source) if source in GENERATED else read_image(source)


def rotate_z(v, degrees: float) -> tuple[float, float, float]:
    a = math.radians(degrees)
    x, y, z = v
    return (x * math.cos(a) - y * math.sin(a), x * math.sin(a) + y * math.cos(a), z)
