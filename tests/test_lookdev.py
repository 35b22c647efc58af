"""Issue 19, the lookdev faces: CLI consistency, RGBA output, tiled renders, turntables, contact sheets,
lights and environment light, the panel's vocabulary, a clean install. Viewer sessions: test_viewer.py."""

from __future__ import annotations

import json
import math
import os
import stat
import tomllib
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from app.cli import main
from app.params import SPEC, ParamError, Params
from tests.support.paths import ROOT



def _err_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


# --------------------------------------------------------------------------------------------------
# the command line

def test_version_and_bench_list(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0 and capsys.readouterr().out.startswith("vfiber ")
    assert main(["bench", "--list"]) == 0
    names = [line.split()[0] for line in capsys.readouterr().out.splitlines()]
    assert {"memory", "extremes", "quality"} <= set(names)


def test_colour_without_brackets_and_the_hint_when_wrong(capsys):
    assert main(["info", "default", "--set", "look.color=0.8,0.5,0.3"]) == 0
    capsys.readouterr()
    assert main(["info", "default", "--set", "look.color=red"]) == 2
    assert "look.color=0.8,0.5,0.3" in _err_line(capsys)


def test_view_takes_set_and_fails_on_a_bad_one_before_any_window(capsys):
    assert main(["view", "default", "--set", "fibers.ringz=3"]) == 2
    assert "fibers.rings" in _err_line(capsys)


def test_explicit_refusal_names_the_cli_option(tmp_path, capsys):
    assert main(["render", "default", "--method", "explicit", "--explicit-budget", "1KiB", "--size", "32x18",
                 "-o", str(tmp_path / "e.png")]) == 2
    line = _err_line(capsys)
    assert "--explicit-budget 1MiB" in line and "ExplicitRenderer(" not in line


def test_info_labels_its_boxes(capsys):
    assert main(["info", "default"]) == 0
    out = capsys.readouterr().out
    assert "container box" in out and "radii included" in out and "bounding box" not in out


def test_every_shader_folder_is_a_listed_package():
    """setuptools prints a page of warnings for each data folder the packages list leaves out."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(config["packages"])
    folders = {f"app.glsl.{d.name}" for d in (ROOT / "glsl").iterdir() if d.is_dir() and not d.name.startswith(".")}
    assert folders <= listed, sorted(folders - listed)


# --------------------------------------------------------------------------------------------------
# RGBA output and tiles

def test_alpha_png_is_the_coverage_and_composites_back_to_the_rgb_render(tmp_path):
    rgb, rgba = tmp_path / "rgb.png", tmp_path / "rgba.png"
    assert main(["render", "default", "--set", "quality.supersample=2", "--size", "96x54", "-o", str(rgb)]) == 0
    assert main(["render", "default", "--set", "quality.supersample=2", "--size", "96x54", "--alpha",
                 "-o", str(rgba)]) == 0
    a = Image.open(rgba)
    assert a.mode == "RGBA"
    px = np.asarray(a).astype(np.float64)
    alpha = px[..., 3] / 255
    assert (alpha == 0).mean() > 0.3 and (alpha == 1).mean() > 0.02 and ((alpha > 0) & (alpha < 1)).any()
    bg = np.round(np.asarray(Params()["look.background"]) ** (1 / 2.2) * 255)
    over = px[..., :3] * alpha[..., None] + (1 - alpha[..., None]) * bg
    assert np.abs(over - np.asarray(Image.open(rgb)).astype(np.float64)).max() <= 2.0


@pytest.mark.parametrize("argv,words", [
    (["-o", "x.jpg"], ["no alpha channel"]),
    (["--output", "depth", "-o", "x.png"], ["no alpha"]),
    (["--method", "explicit", "-o", "x.png"], ["explicit"]),
])
def test_alpha_refuses_what_cannot_carry_it(tmp_path, monkeypatch, capsys, argv, words):
    monkeypatch.chdir(tmp_path)
    assert main(["render", "default", "--alpha", "--size", "16x16", *argv]) == 2
    line = _err_line(capsys)
    assert all(w in line for w in words) and not list(tmp_path.iterdir())


def test_alpha_exr_is_premultiplied_rgba(tmp_path):
    import OpenEXR

    out = tmp_path / "a.exr"
    assert main(["render", "default", "--size", "48x27", "--alpha", "-o", str(out)]) == 0
    with OpenEXR.File(str(out)) as f:
        data = f.channels()["RGBA"].pixels
    assert data.shape == (27, 48, 4)
    assert (data[..., :3] <= data[..., 3:4] + 1e-6).all()          # premultiplied: colour <= alpha
    assert data[..., 3].max() == 1.0 and data[..., 3].min() == 0.0


# the filtered mode's footprint is a pixel's angle: a tile must keep the whole view's (it once took its own
# height's, 2.25x wider here, and the tiled picture differed by up to 51 levels along the fibers' edges)
@pytest.mark.parametrize("thin_fiber_filter", ["off", "coverage"])
def test_tiles_give_the_same_picture_as_one_render(ctx, thin_fiber_filter):
    from app.render.camera import Camera
    from app.render.renderer import Renderer
    from app.render.tiled import render_tiled
    from app.scene.generators import build_scene

    p = Params({"scene.count": 6, "fibers.rings": 4, "quality.filter": thin_fiber_filter})
    scene = build_scene(p)
    r = Renderer(ctx)
    r.set_scene(scene)
    cam = Camera.from_params(p, scene, 150 / 90)
    whole = r.render_quality(p, cam, (150, 90), outputs=("color", "ids"))
    seen = []
    tiled = render_tiled(r, p, cam, (150, 90), outputs=("color", "ids"), tile=40,
                         progress=lambda n, total, s: seen.append((n, total)))
    assert seen[-1] == (12, 12) and [n for n, _ in seen] == list(range(1, 13))
    assert whole.hit.mean() > 0.05
    assert (whole.ids == tiled.ids).all(-1).mean() > 0.999
    assert np.abs(whole.color.astype(int) - tiled.color).max() <= 2


# --------------------------------------------------------------------------------------------------
# turntables and contact sheets

def test_turntable_writes_frames_and_calls_ffmpeg_when_present(tmp_path, monkeypatch, capsys):
    fake = tmp_path / "bin" / "ffmpeg"
    fake.parent.mkdir()
    log = tmp_path / "ffmpeg-args.txt"
    fake.write_text(f'#!/bin/sh\necho "$@" > {log}\nfor last; do :; done\necho video > "$last"\n')
    fake.chmod(fake.stat().st_mode | stat.S_IEXEC)
    monkeypatch.setenv("PATH", f"{fake.parent}{os.pathsep}{os.environ['PATH']}")
    out = tmp_path / "tt"
    assert main(["turntable", "default", "-o", str(out), "--frames", "3", "--size", "64x36", "--alpha"]) == 0
    frames = sorted(out.glob("frame_*.png"))
    assert [f.name for f in frames] == ["frame_0000.png", "frame_0001.png", "frame_0002.png"]
    imgs = [np.asarray(Image.open(f)).astype(int) for f in frames]
    assert all(i.shape == (36, 64, 4) for i in imgs)
    assert np.abs(imgs[0] - imgs[1]).max() > 30                     # the camera turned
    assert (out / "turntable.mp4").exists() and "frame_%04d.png" in log.read_text()
    assert "frame 3/3" in capsys.readouterr().err


def test_light_turntable_turns_the_lights_not_the_camera(tmp_path):
    out = tmp_path / "lt"
    assert main(["turntable", "default", "--light", "-o", str(out), "--frames", "2", "--size", "64x36",
                 "--set", "look.self_shadow=off"]) == 0
    a, b = (np.asarray(Image.open(out / f"frame_000{i}.png")).astype(int) for i in (0, 1))
    bg = np.round(np.asarray(Params()["look.background"]) ** (1 / 2.2) * 255)
    hair_a, hair_b = np.abs(a - bg).max(-1) > 8, np.abs(b - bg).max(-1) > 8
    assert (hair_a == hair_b).mean() > 0.99                       # same silhouette: the camera stayed
    assert np.abs(a - b)[hair_a].max() > 20                        # different light on it


def test_turntable_without_ffmpeg_says_so(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("PATH", str(tmp_path))
    assert main(["turntable", "default", "-o", str(tmp_path / "tt"), "--frames", "2", "--size", "32x18"]) == 0
    assert "ffmpeg is not installed" in capsys.readouterr().out
    assert len(list((tmp_path / "tt").glob("*.png"))) == 2


def test_contact_sheet_has_a_labelled_tile_per_variant(tmp_path):
    from app.contact_sheet import labels_of, layout_of

    out = tmp_path / "sheet.png"
    variants = ["look.model=marschner", "look.color=0.9,0.2,0.1 look.roughness=0.15", "curly-1"]
    argv = ["render", "default", "--size", "120x70", "-o", str(out)]
    for v in variants:
        argv += ["--variant", v]
    assert main(argv) == 0
    assert labels_of(out) == variants
    sheet = np.asarray(Image.open(out).convert("RGB")).astype(int)
    tiles = []
    boxes, label_height = layout_of(out)
    assert len(boxes) == 3 and label_height >= 26             # the long label wraps onto a second line
    for x, y, w, h in boxes:
        tiles.append(sheet[y:y + h, x:x + w])
        strip = sheet[y + h:y + h + label_height, x:x + w]
        assert (strip.max(axis=2) > 150).sum() > 60, "no label text under a tile"
    for i in range(3):
        for j in range(i + 1, 3):
            assert np.abs(tiles[i] - tiles[j]).max() > 30


def test_a_bad_variant_is_one_line(tmp_path, capsys):
    assert main(["render", "default", "--variant", "look.roughnes=0.1", "-o", str(tmp_path / "s.png")]) == 2
    assert "look.roughness" in _err_line(capsys)


# --------------------------------------------------------------------------------------------------
# lights and the environment

def test_lights_as_plain_data_and_the_rim_follows_the_camera():
    from app.render import look

    p = Params({"light.fill_intensity": 0.5, "light.rim_intensity": 2.0, "light.environment": "studio"})
    lights = look.lights(p)
    kinds = [light.kind for light in lights]
    assert kinds[:3] == ["key", "fill", "rim"] and kinds.count("environment") == 8
    for az in (0.0, 90.0):
        rim = next(x for x in look.lights(p, camera_azimuth=az) if x.kind == "rim")
        back = (math.cos(math.radians(az + 180)), math.sin(math.radians(az + 180)))
        horizontal = np.array(rim.direction[:2]) / np.linalg.norm(rim.direction[:2])
        assert np.allclose(horizontal, back, atol=1e-9)          # straight behind the hair
    env = look.environment(p.replace(**{"light.environment_rotation": 30.0, "light.rig_rotation": 10.0}))
    assert env.generated and env.source == "studio" and env.rotation == 40.0
    assert look.lights(Params())[1:] == []                           # the defaults add no light


def test_light_rig_for_an_exporter(tmp_path):
    from app.render import look
    from app.render.environment import read_hdr

    p = Params({"light.rim_intensity": 1.0, "light.environment": "sky", "light.environment_rotation": 20.0})
    rig = look.light_rig(p, str(tmp_path))
    json.dumps(rig)                                              # plain data
    assert [x["kind"] for x in rig["lights"]] == ["key", "rim"]   # lamps only: the image goes as itself
    env = rig["environment"]
    assert env["rotation_degrees"] == 20.0 and env["generated"]
    assert read_hdr(Path(env["image"]).read_bytes()).shape[2] == 3


def test_median_cut_keeps_the_energy_and_finds_the_sun():
    from app.render.environment import generated, lat_long_directions, median_cut

    img = generated("sky")
    d, solid = lat_long_directions(*img.shape[:2])
    total = (img * solid[..., None]).sum(axis=(0, 1))
    lights = median_cut(img, 8)
    assert len(lights) == 8
    assert np.allclose(np.sum([x.color for x in lights], axis=0), total, rtol=1e-9)
    brightest = max(lights, key=lambda x: sum(x.color))
    sun = np.array([math.cos(0.7) * math.cos(2.2), math.cos(0.7) * math.sin(2.2), math.sin(0.7)])
    assert np.dot(brightest.direction, sun) > 0.95


def test_hdr_file_round_trip_and_rle(tmp_path):
    from app.render.environment import environment_lights, generated, read_hdr, write_hdr

    img = generated("studio", 16, 32)
    path = tmp_path / "studio.hdr"
    write_hdr(path, img)
    back = read_hdr(path.read_bytes())
    assert back.shape == img.shape
    # RGBE keeps 8 bits of mantissa against the pixel's largest channel
    assert (np.abs(back - img) <= img.max(axis=-1, keepdims=True) / 128 + 1e-7).all()
    # a run-length encoded scanline file: every channel of every row as one run
    h, w = 2, 8
    head = f"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {h} +X {w}\n".encode()
    row = bytes([2, 2, 0, w]) + b"".join(bytes([128 + w, v]) for v in (128, 64, 32, 129))
    rle = read_hdr(head + row * h)
    assert np.allclose(rle[0, 0], [1.0, 0.5, 0.25])                   # mantissa / 256 * 2^(129 - 128)
    assert len(environment_lights(str(path))) == 8


def test_an_exr_environment_lights_as_the_same_map_generated(tmp_path):
    import OpenEXR

    from app.render.environment import generated

    exr = tmp_path / "studio.exr"
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    OpenEXR.File(header, {"RGB": generated("studio")}).write(str(exr))
    a, b = tmp_path / "gen.png", tmp_path / "file.png"
    assert main(["render", "default", "--set", "light.environment=studio", "--size", "64x36", "-o", str(a)]) == 0
    assert main(["render", "default", "--set", "light.environment=file", "--set", f"light.environment_file={exr}",
                 "--size", "64x36", "-o", str(b)]) == 0
    assert np.array_equal(np.asarray(Image.open(a)), np.asarray(Image.open(b)))


def test_a_missing_environment_file_is_one_line(tmp_path, capsys):
    assert main(["render", "default", "--set", "light.environment=file", "--set",
                 f"light.environment_file={tmp_path / 'nope.exr'}", "--size", "16x16",
                 "-o", str(tmp_path / "x.png")]) == 2
    assert "nope.exr" in _err_line(capsys)
    with pytest.raises(ParamError, match="light.environment_file"):
        from app.render import look
        look.lights(Params({"light.environment": "file"}))


@pytest.mark.parametrize("model", ["kajiya_kay", "marschner"])
def test_each_light_changes_the_image(tmp_path, model):
    def render(*sets: str) -> np.ndarray:
        out = tmp_path / f"r{len(list(tmp_path.iterdir()))}.png"
        argv = ["render", "default", "--size", "96x54", "--set", f"look.model={model}", "-o", str(out)]
        for s in sets:
            argv += ["--set", s]
        assert main(argv) == 0
        return np.asarray(Image.open(out)).astype(int)

    base = render()
    for change in (["light.rim_intensity=3"], ["light.fill_intensity=2"],
                   ["light.environment=studio"], ["light.environment=sky"]):
        img = render(*change)
        assert np.abs(img - base).max() > 20, change
    a = render("light.environment=studio")
    b = render("light.environment=studio", "light.environment_rotation=150")
    assert np.abs(a - b).max() > 10                                  # turning the HDRI moves the light


# --------------------------------------------------------------------------------------------------
# the panel's vocabulary

def test_every_parameter_sits_in_one_section_with_a_label():
    from app.viewer import vocabulary as words

    placed = [k for _, keys in words.sections() for k in keys]
    assert sorted(placed) == sorted(p.key for p in SPEC)
    assert [t for t, _ in words.SECTIONS] == ["Groom", "Strands and fibers", "Shape", "Shading", "Lighting",
                                              "Render"]
    for p in SPEC:
        assert words.label(p.key) and "_" not in words.label(p.key), p.key
    for jargon in ("phi", "rings", "hash", "even spacing", "fraction of container"):
        assert not any(jargon in words.label(p.key) for p in SPEC), jargon
    assert "phi step" in words.THESIS["fibers.phi_step"]


def test_generator_only_controls_are_hidden_for_a_groom():
    from app.viewer import vocabulary as words

    groom = Params({"scene.generator": "groom", "scene.groom_file": "x.hair"})
    carpet = Params()
    for key in ("scene.count", "scene.radius", "scene.length", "scene.bend"):
        ok, why = words.applies(groom, key)
        assert not ok and why, key
    assert words.applies(groom, "scene.groom_cluster")[0] and words.applies(groom, "scene.segments")[0]
    assert words.applies(carpet, "scene.count")[0] and not words.applies(carpet, "scene.groom_file")[0]
    assert not words.applies(carpet, "light.rim_color")[0]
    assert words.applies(Params({"light.rim_intensity": 1.0}), "light.rim_color")[0]


def test_tooltips_carry_the_thesis_name_and_the_key():
    pytest.importorskip("imgui_bundle")
    from app.params import BY_KEY
    from app.viewer.gui import tooltip_text

    text = tooltip_text(BY_KEY["fibers.phi_step"])
    assert "thesis: phi step" in text and "fibers.phi_step" in text


def test_stats_in_plain_words():
    pytest.importorskip("imgui_bundle")
    from app.viewer.gui import stats_lines
    from app.viewer.state import AppState

    s = AppState()
    s.stats.fibers_exact, s.stats.guides, s.stats.label = 86_400, 24, "final exact"
    text = "\n".join(stats_lines(s))
    assert "86,400 strands drawn from 24 guide hairs" in text and "expr." not in text
