"""Contact sheets: several looks side by side, each tile labelled with what makes it different.

``vfiber render TARGET --variant LOOK --variant LOOK ... -o sheet.png``. A variant is a preset or groom
and/or ``key=value`` changes (whitespace between them), applied on top of TARGET and its ``--set``s::

    --variant curly-1                               # another preset, same --set changes
    --variant "look.model=marschner look.roughness=0.2"

The labels are drawn under the tiles (wrapped onto up to three lines) and also stored in the PNG's text
chunks: ``vfiber:labels`` (JSON list) and ``vfiber:tiles`` (JSON list of [x, y, w, h] picture boxes and
the label strip height), so a script (or a test) can read back which tile is which.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from .params import Params

if TYPE_CHECKING:
    import numpy as np

LABEL_KEY = "vfiber:labels"
TILES_KEY = "vfiber:tiles"
LINE_HEIGHT = 18
MAX_LINES = 3
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
            from .errors import UsageError
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
    """Render every look at ``tile`` size into one labelled grid (``compose_sheet``); written atomically
    to ``out``."""
    from .gl.context import create_headless
    from .render.camera import Camera
    from .render.renderer import Renderer
    from .scene.generators import build_scene

    w, h = tile
    tiles = []
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
            tiles.append((label, renderer.render_quality(p, cam, (w, h), outputs=("color",)).color))
            if progress is not None:
                progress(n + 1, len(looks), label)
    return compose_sheet(tiles, out)


def compose_sheet(tiles: list[tuple[str, np.ndarray]], out: str | Path, cols: int | None = None):
    """Pictures made elsewhere (uint8 RGB, all one size), labelled as ``render_contact_sheet`` labels its
    own, ``cols`` to a row (default: as square as it goes); written atomically to ``out``. For comparisons
    whose tiles do not all come from the virtual renderer (app/bench/looks.py: the strand reference)."""
    from PIL import Image, ImageDraw, PngImagePlugin

    from .atomic import atomic_path

    if not tiles:
        raise ValueError("compose_sheet: no tiles")
    h, w = tiles[0][1].shape[:2]
    if any(img.shape[:2] != (h, w) for _, img in tiles):
        raise ValueError(f"compose_sheet: every tile must be {w}x{h}")
    cols = cols or math.ceil(math.sqrt(len(tiles)))
    rows = math.ceil(len(tiles) / cols)
    font = _font(14)
    measure = ImageDraw.Draw(Image.new("RGB", (1, 1)))
    wrapped = [_wrap(measure, label, font, w - 12) for label, _ in tiles]
    label_height = 8 + LINE_HEIGHT * max(len(lines) for lines in wrapped)
    boxes = tile_boxes(len(tiles), (w, h), label_height, cols)
    sheet = Image.new("RGB", (cols * (w + GAP) + GAP, rows * (h + label_height + GAP) + GAP), SHEET_BG)
    draw = ImageDraw.Draw(sheet)
    for (x, y, _, _), (_, img), lines in zip(boxes, tiles, wrapped):
        sheet.paste(Image.fromarray(img), (x, y))
        for i, line in enumerate(lines):
            draw.text((x + 6, y + h + 4 + i * LINE_HEIGHT), line, fill=LABEL_FG, font=font)
    info = PngImagePlugin.PngInfo()
    info.add_text(LABEL_KEY, json.dumps([label for label, _ in tiles]))
    info.add_text(TILES_KEY, json.dumps({"boxes": boxes, "label_height": label_height}))
    with atomic_path(out) as tmp:
        sheet.save(tmp, format="PNG", pnginfo=info)
    return sheet


def _wrap(draw, text: str, font, width: int) -> list[str]:
    """Words onto lines no wider than ``width``; past MAX_LINES the last line ends with an ellipsis."""
    lines: list[str] = []
    for word in text.split():
        if lines and draw.textlength(lines[-1] + " " + word, font=font) <= width:
            lines[-1] += " " + word
        else:
            lines.append(word)
    lines = lines or [""]
    if len(lines) > MAX_LINES:
        lines = lines[:MAX_LINES]
        lines[-1] += " ..."
    return [_fit(draw, line, font, width) for line in lines]


def _fit(draw, text: str, font, width: int) -> str:
    """A line cut with an ellipsis where it would run past the tile."""
    if draw.textlength(text, font=font) <= width:
        return text
    while text and draw.textlength(text + "...", font=font) > width:
        text = text[:-1]
    return text + "..."


def labels_of(path: str | Path) -> list[str]:
    from PIL import Image

    return json.loads(Image.open(path).text[LABEL_KEY])


def layout_of(path: str | Path) -> tuple[list[tuple[int, int, int, int]], int]:
    """The picture boxes of a written sheet and the height of the label strip under each."""
    from PIL import Image

    layout = json.loads(Image.open(path).text[TILES_KEY])
    return [tuple(b) for b in layout["boxes"]], layout["label_height"]


def tile_boxes(count: int, tile: tuple[int, int], label_height: int,
               cols: int | None = None) -> list[tuple[int, int, int, int]]:
    """(x, y, w, h) of each tile's picture in a sheet of ``count`` tiles (the label strip lies below)."""
    w, h = tile
    cols = cols or math.ceil(math.sqrt(count))
    return [(GAP + (n % cols) * (w + GAP), GAP + (n // cols) * (h + label_height + GAP), w, h)
            for n in range(count)]
