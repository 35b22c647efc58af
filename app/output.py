"""Output files of a render: what ``--output`` kind and image type turn a frame into (PNG, EXR, NPY).

Shared by ``vfiber render``, the turntable and the contact sheet, so every face writes the same pixels.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .errors import UsageError
from .params import Params

OUTPUTS = ("shaded", "id", "depth", "normal", "ring", "cost")
IMAGE_SUFFIXES = (".npy", ".exr", ".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp")  # what write_output writes


def unpremultiplied_rgba(frame, p: Params) -> np.ndarray:
    """(H, W, 4) uint8: the fibers' own colour with their coverage as alpha (background taken out), so the
    picture composites over any plate. The renderer hands back colour over the background and the coverage;
    where coverage is 0 the colour is black and fully transparent."""
    bg = np.round(np.clip(np.asarray(p["look.background"]), 0, 1) ** (1 / 2.2) * 255)
    a = frame.coverage.astype(np.float64)[..., None]
    premultiplied = frame.color.astype(np.float64) - (1.0 - a) * bg
    straight = np.where(a > 0, premultiplied / np.maximum(a, 1e-6), 0.0)
    rgb = np.clip(np.round(straight), 0, 255)
    return np.concatenate([rgb, np.round(a * 255)], axis=-1).astype(np.uint8)


def output_image(frame, kind: str, p: Params, alpha: bool = False) -> np.ndarray:
    from .render import debug_views as dv

    if kind == "shaded":
        return unpremultiplied_rgba(frame, p) if alpha else frame.color
    if kind == "id":
        return dv.fiber_id_image(frame.ids)
    if kind == "ring":
        return dv.ring_image(frame.ids, p["fibers.rings"])
    if kind == "depth":
        return dv.depth_image(frame.geom)
    if kind == "normal":
        return dv.normal_image(frame.geom)
    return dv.cost_image(frame.cost)


def output_data(frame, kind: str, p: Params | None = None, alpha: bool = False) -> np.ndarray:
    """Raw values for .npy/.exr: ids as uint32, the rest float32. Shaded with ``alpha``: premultiplied
    RGBA (the compositors' convention for EXR), coverage as alpha."""
    if kind == "shaded":
        if alpha:
            rgba = unpremultiplied_rgba(frame, p).astype(np.float32) / 255.0
            rgba[..., :3] *= rgba[..., 3:4]
            return rgba
        return frame.color.astype(np.float32) / 255.0
    if kind in ("id", "ring"):
        return frame.ids if kind == "id" else frame.ids[..., 1:2]
    if kind == "depth":
        return frame.geom[..., 3:4]
    if kind == "normal":
        return frame.geom[..., :3]
    return frame.cost


def write_output(path: Path, frame, kind: str, p: Params, alpha: bool = False) -> None:
    from PIL import Image

    from .atomic import atomic_path

    suffix = path.suffix.lower()
    with atomic_path(path) as tmp:
        if suffix == ".npy":
            with open(tmp, "wb") as f:
                np.save(f, output_data(frame, kind, p, alpha))
        elif suffix == ".exr":
            import OpenEXR

            data = output_data(frame, kind, p, alpha)
            if data.dtype != np.uint32:
                data = data.astype(np.float32)
            channels = {1: {"Y": data[..., 0]}, 3: {"RGB": data}, 4: {"RGBA": data}}[data.shape[-1]]
            header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
            OpenEXR.File(header, channels).write(str(tmp))
        elif suffix in (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp"):
            img = output_image(frame, kind, p, alpha)
            Image.fromarray(img).save(tmp, format=Image.registered_extensions()[suffix])
        else:
            raise UsageError(f"{path}: unknown image type {suffix!r}; use .png, .exr or .npy")
