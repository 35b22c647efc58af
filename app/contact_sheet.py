"""Contact sheets: several looks side by side, each tile labelled with what makes it different.

``vfiber render TARGET --variant LOOK --variant LOOK ... -o sheet.png``. A variant is a preset or groom
and/or ``key=value`` changes (whitespace between them), applied on top of TARGET and its ``--set``s::

    --variant curly-1                               # another preset, same --set changes
    --variant "look.model=marschner look.roughness=0.2"

The labels are drawn under the tiles and also stored in the PNG's text chunk ``vfiber:labels`` (JSON),
so a script (or a test) can read back which tile is which.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path

from .params import Params

LABEL_KEY = "vfiber:labels"
LABEL_HEIGHT = 26
GAP = 4
SHEET_BG = (30, 31, 34)
LABEL_FG = (225, 225, 225)


def parse_variants(base_target: str | None, base_sets: list[str], variants: list[str],
                   resolve: Callable, mode: str | None = None) -> list[tuple[str, Params]]:
    """(label, parameters) per variant; a bad variant fails with its own text in the message."""
    looks = []
    for text in variants:
        tokens = text.split()
        targets = [t for t in tokens if "=" not in t]
        sets = [t for t in tokens if "=" in t]
        if len(targets) > 1:
            from .cli import UsageError
            raise UsageError(f"--variant {text!r}: at most one preset or groom per variant")
        p, _ = resolve(targets[0] if targets else base_target, list(base_sets) + sets)
        if mode:
            p = p.replace(**{"quality.mode": mode})
        looks.append((text.strip() or "(base)", p))
    return looks


def _font(size: int):
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=size)       # Pillow >= 10.1: a scalable bundled font
    except TypeError:
        return ImageFont.load_default()


def render_contact_sheet(looks: list[tuple[str, Params]], tile: tuple[int, int], out: str | Path,
                         progress: Callable[[int, int, str], None] | None = None):
    """Render every look at ``tile`` size into one labelled grid; written atomically to ``out``."""
    from PIL import Image, ImageDraw, PngImagePlugin

    from .atomic import atomic_path
    from .gl.context import create_headless
    from .render.camera import Camera
    from .render.renderer import Renderer
    from .scene.generators import build_scene

    w, h = tile
    cols = math.ceil(math.sqrt(len(looks)))
    rows = math.ceil(len(looks) / cols)
    sheet = Image.new("RGB", (cols * (w + GAP) + GAP, rows * (h + LABEL_HEIGHT + GAP) + GAP), SHEET_BG)
    draw = ImageDraw.Draw(sheet)
    font = _font(14)
    scenes: dict[tuple, object] = {}
    with create_headless() as gl:
        renderer = Renderer(gl.ctx)
        shown = None
        for n, (label, p) in enumerate(looks):
            key = tuple((k, v) for k, v in p.values.items() if k.startswith("scene."))
            if key not in scenes:
                scenes[key] = build_scene(p)
            scene = scenes[key]
            if shown is not scene:
                renderer.set_scene(scene)
                shown = scene
            cam = Camera.from_params(p, scene, w / h)
            img = renderer.render_quality(p, cam, (w, h), outputs=("color",)).color
            x = GAP + (n % cols) * (w + GAP)
            y = GAP + (n // cols) * (h + LABEL_HEIGHT + GAP)
            sheet.paste(Image.fromarray(img), (x, y))
            draw.text((x + 6, y + h + 5), _fit(draw, label, font, w - 12), fill=LABEL_FG, font=font)
            if progress is not None:
                progress(n + 1, len(looks), label)
    info = PngImagePlugin.PngInfo()
    info.add_text(LABEL_KEY, json.dumps([label for label, _ in looks]))
    with atomic_path(out) as tmp:
        sheet.save(tmp, format="PNG", pnginfo=info)
    return sheet


def _fit(draw, text: str, font, width: int) -> str:
    """The label, cut with an ellipsis where it would run past the tile."""
    if draw.textlength(text, font=font) <= width:
        return text
    while text and draw.textlength(text + "...", font=font) > width:
        text = text[:-1]
    return text + "..."


def labels_of(path: str | Path) -> list[str]:
    from PIL import Image

    return json.loads(Image.open(path).text[LABEL_KEY])


def tile_boxes(count: int, tile: tuple[int, int]) -> list[tuple[int, int, int, int]]:
    """(x, y, w, h) of each tile's picture in a sheet of ``count`` tiles (the label strip lies below)."""
    w, h = tile
    cols = math.ceil(math.sqrt(count))
    return [(GAP + (n % cols) * (w + GAP), GAP + (n // cols) * (h + LABEL_HEIGHT + GAP), w, h)
            for n in range(count)]


def label_box(box: tuple[int, int, int, int]) -> tuple[int, int, int, int]:
    x, y, w, h = box
    return x, y + h, w, LABEL_HEIGHT


__all__ = ["parse_variants", "render_contact_sheet", "labels_of", "tile_boxes", "label_box"]
