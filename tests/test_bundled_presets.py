"""The bundled preset library: the looks of the thesis's figures (3.10, Figures 22-34 and 39) plus fur on
a sphere. Every preset loads, says in one line what you should see, really shows the feature it is named
for, puts fibers in a thumbnail, and keeps its geometry equal to a golden recorded on llvmpipe.

The goldens are ring images (which ring of which container each pixel hit), not shaded pictures: the
shading model changes on its own schedule, and a change of colour must not read as a broken layout. The
shaded thumbnails live in the gallery, docs/presets.md.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from app.cli import main as cli_main
from app.presets import bundled_names, bundled_presets
from app.render.camera import Camera
from app.render.debug_views import ring_image
from app.render.renderer import is_shaped
from app.scene.generators import build_scene
from tests.support.goldens import check_golden, require_llvmpipe
from tests.support.paths import ROOT, GOLDENS

GOLDENS = GOLDENS / "presets"
GALLERY = ROOT / "docs" / "presets.md"
THUMB = (128, 72)
HIT_FLOOR = 0.05       # fraction of a thumbnail that must be fibers: less means the camera lost the look
TOLERANCE = 0.005      # fraction of pixels allowed to differ by more than 8/255 from the golden
# looks of sub-pixel fibers flip more edge pixels when another LLVM rounds atan() differently
TOLERANCE_FOR = {"default": 0.01, "carpet": 0.01, "fur-ball": 0.01}

# name -> what the preset must set to show its figure (the thesis's pattern numbers are kept: curly
# pattern 1 is Figure 29, pattern 2 Figure 28; twisted and curled pattern 1 is Figure 34, 2 Figure 33)
FEATURES: dict[str, dict] = {
    "straight": {"scene.generator": "single", "scene.segments": 1, "scene.bend": 0.0},
    "deformed": {"scene.generator": "single", "scene.bend": lambda v: v >= 45.0},
    "ellipsoid": {"scene.generator": "single", "shape.ellipsoid": lambda v: v >= 0.5},
    "curly-1": {"shape.curl_pattern": "helix", "shape.curl_amplitude": lambda v: v > 0, "shape.twist": 0.0},
    "curly-2": {"shape.curl_pattern": "wave", "shape.curl_amplitude": lambda v: v > 0, "shape.twist": 0.0},
    "twisted-1": {"shape.twist_pattern": "uniform", "shape.twist": lambda v: v != 0,
                  "shape.curl_amplitude": 0.0},
    "twisted-2": {"shape.twist_pattern": "ramped", "shape.twist": lambda v: v != 0,
                  "shape.curl_amplitude": 0.0},
    "twisted-3": {"shape.twist_pattern": "alternating", "shape.twist": lambda v: v != 0,
                  "shape.curl_amplitude": 0.0},
    "twisted-curled-1": {"shape.twist": lambda v: v != 0, "shape.curl_amplitude": lambda v: v > 0,
                         "shape.curl_pattern": "helix"},
    "twisted-curled-2": {"shape.twist": lambda v: v != 0, "shape.curl_amplitude": lambda v: v > 0,
                         "shape.curl_pattern": "wave"},
    "carpet": {"scene.generator": "carpet", "scene.count": lambda v: v >= 100},
    "fur-ball": {"scene.generator": "furball", "scene.count": lambda v: v >= 100},
}
LIBRARY = {"default", *FEATURES}

PRESETS = {p.path.stem: p for p in bundled_presets()}
NAMES = sorted(PRESETS)


def test_the_library_has_every_look_of_the_issue():
    missing = LIBRARY - set(bundled_names())
    assert not missing, f"bundled presets missing: {', '.join(sorted(missing))}"


@pytest.mark.parametrize("name", NAMES)
def test_preset_says_what_you_should_see(name):
    preset = PRESETS[name]
    assert preset.name == name, f"{preset.path}: name = {preset.name!r}, the file is {name}.toml"
    text = preset.description
    assert text.startswith("You should see "), f"{preset.path}: start the description 'You should see ...'"
    assert "\n" not in text and len(text) <= 240, f"{preset.path}: keep the description to one short line"
    assert text.endswith("."), f"{preset.path}: end the description with a full stop"


@pytest.mark.parametrize("name", sorted(FEATURES))
def test_preset_shows_the_feature_it_is_named_for(name):
    p = PRESETS[name].params
    for key, want in FEATURES[name].items():
        ok = want(p[key]) if callable(want) else p[key] == want
        assert ok, f"{name}: {key} = {p[key]!r} does not show the look this preset is named for"
    if is_shaped(p):
        # curved fibers cost less per segment when each segment spans a short height range
        assert 6 <= p["scene.segments"] <= 8, f"{name}: curved fibers want scene.segments 6-8"
    assert p["camera.distance"] > 0, f"{name}: frame the look with an explicit camera.distance"


def test_vfiber_presets_lists_every_bundled_preset(capsys):
    assert cli_main(["presets"]) == 0
    lines = capsys.readouterr().out.splitlines()
    for name, preset in PRESETS.items():
        line = next((ln for ln in lines if ln.split(maxsplit=1)[:1] == [preset.name]), None)
        assert line is not None, f"vfiber presets does not list {name}"
        assert line.rstrip().endswith(preset.description), f"vfiber presets: {name} without its description"


def test_gallery_shows_every_preset():
    """docs/presets.md: each preset's name, its description word for word, and a thumbnail that exists."""
    text = GALLERY.read_text(encoding="utf-8")
    for name, preset in PRESETS.items():
        assert f"## {name}\n" in text, f"{GALLERY.name}: no '## {name}' section"
        section = text.split(f"## {name}\n", 1)[1].split("\n## ", 1)[0]
        assert preset.description in section, f"{GALLERY.name}: {name}'s description differs from the preset"
        images = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", section)
        assert images, f"{GALLERY.name}: {name} has no thumbnail"
        for rel in images:
            assert (GALLERY.parent / rel).is_file(), f"{GALLERY.name}: {rel} does not exist"


@pytest.mark.parametrize("name", NAMES)
def test_thumbnail_shows_fibers_and_matches_golden(gl, renderer, regen_goldens, name):
    p = PRESETS[name].params
    scene = build_scene(p)
    renderer.set_scene(scene)
    cam = Camera.from_params(p, scene)
    frame = renderer.render(p, cam, THUMB, outputs=("color", "ids"))
    w, h = THUMB
    assert frame.color.shape == (h, w, 3) and frame.color.dtype == np.uint8
    covered = frame.hit.mean()
    assert covered > HIT_FLOOR, f"{name}: only {covered:.1%} of the thumbnail is fibers"
    bg = np.round(np.clip(np.asarray(p["look.background"]), 0, 1) ** (1 / 2.2) * 255)
    stands_out = (np.abs(frame.color[frame.hit].astype(int) - bg).max(-1) > 8).mean()
    assert stands_out > 0.5, f"{name}: the fibers are hard to tell from the background"

    require_llvmpipe(gl)
    img = ring_image(frame.ids, p["fibers.rings"])
    check_golden(gl, img, GOLDENS / f"{name}.png", TOLERANCE_FOR.get(name, TOLERANCE), regen_goldens,
                 f"preset-{name}", meta_extra={"size": list(THUMB), "image": "ring"})
