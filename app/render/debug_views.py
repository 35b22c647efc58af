"""Turning the renderer's raw outputs into pictures people would rather look at than read.

Shared by the command line (``--output id|ring|depth|normal|cost``), the viewer's debug views and the
benchmark reports. Every function takes the arrays of a ``Frame`` and returns an (H, W, 3) uint8 image.
"""

from __future__ import annotations

import numpy as np

from ..fibers import lowbias32

# A perceptually ordered ramp (dark blue -> teal -> yellow -> red), sampled at 6 stops.
_HEAT = np.array([[0.05, 0.03, 0.25], [0.1, 0.3, 0.6], [0.1, 0.6, 0.6], [0.5, 0.8, 0.3],
                  [0.98, 0.85, 0.2], [0.9, 0.2, 0.1]])


def hash_colors(keys: np.ndarray) -> np.ndarray:
    """A stable, well-spread colour per integer key; key 0 (no fiber) is black."""
    h = lowbias32(keys.astype(np.uint32))
    rgb = np.stack([(h >> np.uint32(s)) & np.uint32(255) for s in (0, 8, 16)], -1).astype(np.float64)
    rgb = 60 + rgb * (195 / 255)                      # never too dark to see against the background
    return np.where((keys == 0)[..., None], 0, rgb).astype(np.uint8)


def fiber_id_image(ids: np.ndarray) -> np.ndarray:
    """One colour per fiber: (guide, ring, fiber) hashed together."""
    g, r, f = (ids[..., k].astype(np.uint32) for k in range(3))
    with np.errstate(over="ignore"):
        key = lowbias32(g * np.uint32(73856093) ^ lowbias32(r * np.uint32(19349663) ^ f))
    return hash_colors(np.where(g > 0, key | np.uint32(1), 0))


def ring_image(ids: np.ndarray, rings: int) -> np.ndarray:
    """Ring index on the heat ramp (outer ring dark, inner ring hot)."""
    hit = ids[..., 0] > 0
    return heat(np.where(hit, ids[..., 1] + 1.0, 0.0), vmax=float(rings), mask=hit)


def depth_image(geom: np.ndarray) -> np.ndarray:
    t = geom[..., 3]
    hit = t > 0
    if not hit.any():
        return np.zeros(t.shape + (3,), np.uint8)
    lo, hi = np.percentile(t[hit], [1, 99])
    v = np.clip((t - lo) / max(hi - lo, 1e-30), 0, 1)
    g = np.where(hit, 255 * (1 - 0.85 * v), 0)
    return np.repeat(g[..., None], 3, -1).astype(np.uint8)


def normal_image(geom: np.ndarray) -> np.ndarray:
    n = geom[..., :3]
    hit = np.any(n != 0, -1)
    return np.where(hit[..., None], np.round((n * 0.5 + 0.5) * 255), 0).clip(0, 255).astype(np.uint8)


def heat(values: np.ndarray, vmax: float | None = None, mask: np.ndarray | None = None) -> np.ndarray:
    """Values on the heat ramp, 0..vmax (default: 99th percentile of the masked values)."""
    mask = values > 0 if mask is None else mask
    if vmax is None:
        vmax = float(np.percentile(values[mask], 99)) if mask.any() else 1.0
    x = np.clip(values / max(vmax, 1e-30), 0, 1) * (len(_HEAT) - 1)
    i = np.minimum(x.astype(int), len(_HEAT) - 2)
    f = (x - i)[..., None]
    rgb = _HEAT[i] * (1 - f) + _HEAT[i + 1] * f
    return np.where(mask[..., None], rgb * 255, 0).astype(np.uint8)


def cost_image(cost: np.ndarray, vmax: float | None = None, legend: bool = True) -> np.ndarray:
    """Fiber tests per pixel as a heat map, with a colour-scale legend along the bottom."""
    tests = cost[..., 0]
    covered = cost[..., 2] > 0
    if vmax is None:
        vmax = float(np.percentile(tests[covered], 99)) if covered.any() else 1.0
    img = heat(tests, vmax, covered)
    if legend and img.shape[0] >= 40 and img.shape[1] >= 64:
        img = heat_legend(img, vmax, "fiber tests / pixel")
    return img


def heat_legend(img: np.ndarray, vmax: float, unit: str) -> np.ndarray:
    """A colour-scale bar from 0 to ``vmax`` (labelled in ``unit``) along the bottom of a heat map."""
    from PIL import Image, ImageDraw

    img = img.copy()
    h, w = img.shape[:2]
    bar = np.linspace(0, vmax, w - 20)[None].repeat(8, 0)
    img[h - 18:h - 10, 10:w - 10] = heat(bar, vmax, np.ones_like(bar, bool))
    pil = Image.fromarray(img)
    draw = ImageDraw.Draw(pil)
    draw.text((10, h - 32), "0", fill=(255, 255, 255))
    label = f"{vmax:.0f} {unit}"
    draw.text((w - 10 - 6 * len(label), h - 32), label, fill=(255, 255, 255))
    return np.asarray(pil)
