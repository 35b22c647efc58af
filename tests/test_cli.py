"""The command line: files written, one-line errors, exit codes."""

from __future__ import annotations


import numpy as np
import pytest
from PIL import Image

from app.cli import main
from app.params import ParamError
from tests.support.paths import HAIR_DATA


def test_render_writes_png_and_npy(tmp_path, capsys):
    png = tmp_path / "a.png"
    assert main(["render", "default", "--size", "64x36", "-o", str(png)]) == 0
    assert Image.open(png).size == (64, 36)
    npy = tmp_path / "ids.npy"
    assert main(["render", "--set", "fibers.rings=4", "--output", "id", "--size", "48x32", "-o", str(npy)]) == 0
    ids = np.load(npy)
    assert ids.shape == (32, 48, 4) and ids.dtype == np.uint32 and (ids[..., 0] > 0).any()


@pytest.mark.parametrize("kind", ["depth", "normal", "ring", "cost"])
def test_every_output_kind_writes_an_exr(tmp_path, kind):
    out = tmp_path / f"{kind}.exr"
    assert main(["render", "default", "--output", kind, "--size", "40x24", "-o", str(out)]) == 0
    assert out.stat().st_size > 0


def test_explicit_method_renders_and_refuses_over_budget(tmp_path, capsys):
    out = tmp_path / "e.png"
    assert main(["render", "default", "--method", "explicit", "--size", "64x36", "-o", str(out)]) == 0
    assert main(["render", "default", "--method", "explicit", "--explicit-budget", "1KiB", "--size", "64x36",
                 "-o", str(tmp_path / "f.png")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "budget" in err[0] and "Traceback" not in err[0]
    assert not (tmp_path / "f.png").exists()


@pytest.mark.parametrize("argv,words", [
    (["render", "--set", "fibers.ringz=3", "-o", "x.png"], ["fibers.rings"]),
    (["render", "--set", "fibers.rings=100", "-o", "x.png"], ["fibers.rings", "[1, 64]"]),
    (["render", "--size", "big", "-o", "x.png"], ["WIDTHxHEIGHT"]),
    (["render", "no-such-preset", "-o", "x.png"], ["default"]),
    (["render", "-o", "/no/such/folder/x.png"], ["does not exist"]),
    (["info", "missing.hair"], ["no such groom file"]),
])
def test_errors_are_one_line_with_exit_2(tmp_path, capsys, monkeypatch, argv, words):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    for w in words:
        assert w in err[0]


def test_a_failed_write_keeps_the_old_file(tmp_path, monkeypatch):
    out = tmp_path / "keep.png"
    out.write_bytes(b"old picture")
    monkeypatch.setattr(Image.Image, "save", lambda *a, **k: (_ for _ in ()).throw(OSError("disk full")))
    assert main(["render", "default", "--size", "16x16", "-o", str(out)]) == 2
    assert out.read_bytes() == b"old picture"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.png"]


def test_info_reports_fibers_and_constant_bytes(capsys):
    assert main(["info", "default"]) == 0
    a = capsys.readouterr().out
    assert main(["info", "default", "--set", "fibers.phi_step=180"]) == 0
    b = capsys.readouterr().out
    line = lambda text, key: next(x for x in text.splitlines() if x.startswith(key))  # noqa: E731
    assert line(a, "scene GPU bytes") == line(b, "scene GPU bytes")
    assert "86400 exact" in line(a, "fibers  ")


SINTEL = HAIR_DATA / "sintel_hair.tfx"


@pytest.mark.skipif(not SINTEL.exists(), reason=f"shared hair data not found at {SINTEL}")
def test_viewer_and_info_show_one_explicit_figure_on_sintel(capsys):
    """`vfiber view` and `vfiber info` once showed 150.3 MiB against 56.5 MiB for the same scene: both now
    show what the explicit baseline allocates (render.explicit.explicit_bytes)."""
    from types import SimpleNamespace

    from app.presets import resolve_params
    from app.render.explicit import estimate_bytes
    from app.scene.generators import build_scene
    from app.viewer.app import Viewer
    from app.viewer.state import AppState

    assert main(["info", str(SINTEL)]) == 0
    line = next(ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("GPU explicit"))
    info_bytes = int(line.split()[2].replace(",", ""))

    p, _ = resolve_params(str(SINTEL))
    scene = build_scene(p)
    state = AppState(params=p)
    Viewer._update_counts(SimpleNamespace(state=state, scene=scene))   # the viewer's own count, no window
    assert state.stats.explicit_bytes == info_bytes == estimate_bytes(scene, p)
    # 1,368 segments x 148 fibers (fibers.groom_auto's fill for sintel) x 12 B + 1,368 rows x 80 B (2.4 MiB)
    assert info_bytes == 2_539_008

    # tapered fibers also store where they end (2 B more per instance): both faces still agree
    tapered_sets = ["strand.tip_width=0.2"]
    assert main(["info", str(SINTEL), *sum((["--set", s] for s in tapered_sets), [])]) == 0
    line = next(ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("GPU explicit"))
    tapered_bytes = int(line.split()[2].replace(",", ""))
    p, _ = resolve_params(str(SINTEL), tapered_sets)
    state = AppState(params=p)
    Viewer._update_counts(SimpleNamespace(state=state, scene=scene))
    assert state.stats.explicit_bytes == tapered_bytes == estimate_bytes(scene, p)
    assert tapered_bytes == 2_539_008 + 1_368 * 148 * 2


def test_set_is_parsed_once_for_every_face(tmp_path):
    """The command line and the OSL export read --set alike, the bracket-free colour included."""
    from app.export.osl import load_look
    from app.presets import resolve_params

    sets = ["look.color=0.8,0.5,0.3", "fibers.rings=12"]
    cli_params, _ = resolve_params("default", sets)
    osl_params, _, _ = load_look("default", sets)
    assert cli_params["look.color"] == osl_params["look.color"] == (0.8, 0.5, 0.3)
    assert cli_params == osl_params
    with pytest.raises(ParamError) as cli_err:
        resolve_params("default", ["look.color=red"])
    with pytest.raises(ParamError) as osl_err:
        load_look("default", ["look.color=red"])
    assert str(cli_err.value) == str(osl_err.value) and str(cli_err.value).startswith("--set: ")


def test_budget_and_size_options_read_units(tmp_path, capsys):
    with pytest.raises(SystemExit):
        main(["render", "default", "--explicit-budget", "lots", "-o", str(tmp_path / "x.png")])
    assert "'lots' is not a size" in capsys.readouterr().err
    assert main(["render", "default", "--size", "0x10", "-o", str(tmp_path / "x.png")]) == 2
    assert "between 1 and 16384" in capsys.readouterr().err


# --------------------------------------------------------------------------------------------------
# a preset's look on a groom (issue 15)

needs_sintel = pytest.mark.skipif(not SINTEL.exists(), reason=f"shared hair data not found at {SINTEL}")
LOOK = "curly-1"


def _rgb(path) -> np.ndarray:
    return np.asarray(Image.open(path).convert("RGB")).astype(int)


def _look_sets(name: str) -> list[str]:
    """--set texts for every look value of the preset that differs from a bare groom's."""
    from app.presets import find_preset, look_values, resolve_params

    groom, _ = resolve_params(str(SINTEL))
    out = []
    for k, v in look_values(find_preset(name).params).items():
        if v != groom[k]:
            out.append(f"{k}={','.join(repr(float(x)) for x in v)}" if isinstance(v, tuple) else
                       f"{k}={v!r}" if isinstance(v, float) else f"{k}={v}")
    return out


@needs_sintel
def test_render_puts_the_presets_look_on_the_groom_and_nothing_else(tmp_path, capsys):
    """The picture changes, and it is the picture of the groom with the preset's look values typed as --set:
    the groom's containers and camera are the ones it has alone."""
    from app.presets import resolve_params
    from app.render.camera import Camera
    from app.scene.generators import build_scene

    size = ["--size", "96x54"]
    plain, before, after, typed = (tmp_path / f"{n}.png" for n in ("plain", "before", "after", "typed"))
    assert main(["render", str(SINTEL), *size, "-o", str(plain)]) == 0
    assert main(["render", "--preset", LOOK, str(SINTEL), *size, "-o", str(before)]) == 0  # the order
    assert main(["render", str(SINTEL), "--preset", LOOK, *size, "-o", str(after)]) == 0
    sets = [a for s in _look_sets(LOOK) for a in ("--set", s)]
    assert len(sets) >= 10   # curly-1 differs in rings, spacing, radius, curl, colour, light...
    assert main(["render", str(SINTEL), *sets, *size, "-o", str(typed)]) == 0
    assert "with the look of" in capsys.readouterr().out
    assert np.abs(_rgb(plain) - _rgb(after)).max() > 40                  # the look shows
    assert np.array_equal(_rgb(before), _rgb(after))
    assert np.array_equal(_rgb(after), _rgb(typed))                      # and it is only the look

    p0, _ = resolve_params(str(SINTEL))
    p1, _ = resolve_params(str(SINTEL), look=LOOK)
    s0, s1 = build_scene(p0), build_scene(p1)
    assert s0.segments.tobytes() == s1.segments.tobytes() and s0.origin.tobytes() == s1.origin.tobytes()
    c0, c1 = Camera.from_params(p0, s0, 16 / 9), Camera.from_params(p1, s1, 16 / 9)
    for field in ("position", "target", "up"):
        assert getattr(c0, field).tobytes() == getattr(c1, field).tobytes(), field
    assert (c0.fov, c0.near, c0.far) == (c1.fov, c1.near, c1.far)


@needs_sintel
def test_turntable_info_and_export_osl_take_the_look_on_a_groom(tmp_path, capsys):
    import json

    for look in (None, LOOK):
        extra = ["--preset", look] if look else []
        assert main(["turntable", str(SINTEL), *extra, "-o", str(tmp_path / f"tt-{look}"), "--frames", "1",
                     "--size", "64x36", "--no-video"]) == 0
    a, b = (_rgb(tmp_path / f"tt-{look}" / "frame_0000.png") for look in (None, LOOK))
    assert np.abs(a - b).max() > 40
    capsys.readouterr()
    assert main(["info", str(SINTEL), "--preset", LOOK]) == 0
    out = capsys.readouterr().out
    assert "with the look of" in out and LOOK in out
    js = tmp_path / "look.json"
    assert main(["export-osl", str(SINTEL), "--preset", LOOK, "--params-only", "-o", str(js)]) == 0
    doc = json.loads(js.read_text())
    from app.export.osl import osl_values
    from app.presets import resolve_params
    on_groom, alone = (osl_values(resolve_params(str(SINTEL), look=look)[0]) for look in (LOOK, None))
    assert doc["preset"] == "sintel_hair-curly-1" and doc["parameters"] == on_groom != alone
    assert doc["parameters"]["fibers_rings"] == 3 and doc["parameters"]["shape_curl_amplitude"] == 0.5
    assert doc["parameters"]["scene_radius"] == alone["scene_radius"]    # the groom's scene, not curly-1's 0.3


@needs_sintel
def test_a_contact_sheet_of_a_groom_shows_each_look_on_the_groom(tmp_path):
    from app.contact_sheet import labels_of, layout_of

    sheet_path = tmp_path / "sheet.png"
    variants = [LOOK, "fur-ball", "look.roughness=0.15"]
    argv = ["render", str(SINTEL), "--size", "96x54", "-o", str(sheet_path)]
    for v in variants:
        argv += ["--variant", v]
    assert main(argv) == 0
    assert labels_of(sheet_path) == variants
    sheet = _rgb(sheet_path)
    boxes, _ = layout_of(sheet_path)
    for (x, y, w, h), single in zip(boxes, [["--preset", LOOK], ["--preset", "fur-ball"],
                                            ["--set", "look.roughness=0.15"]]):
        one = tmp_path / "one.png"
        assert main(["render", str(SINTEL), *single, "--size", f"{w}x{h}", "-o", str(one)]) == 0
        assert np.array_equal(sheet[y:y + h, x:x + w], _rgb(one)), single   # the tile is the look on the groom
    again = tmp_path / "again.png"                     # the groom given as --preset alone is the same TARGET
    assert main(["render", "--preset", str(SINTEL), "--size", "96x54", "-o", str(again)]
                + [a for v in variants for a in ("--variant", v)]) == 0
    assert np.array_equal(_rgb(again), sheet)


@pytest.mark.parametrize("argv,part", [
    (["render", str(SINTEL), "--preset", "curly-9"], "did you mean 'curly-"),
    (["render", str(SINTEL), "--preset", str(HAIR_DATA / "Bangs_100.hair")], "two grooms given"),
    (["render", "default", "--preset", LOOK], "two scenes given"),
    (["turntable", "default", "--preset", LOOK], "two scenes given"),
    (["render", str(SINTEL), "--variant", "curly-9"], "did you mean 'curly-"),
    (["export-osl", "default", "--preset", LOOK], "two scenes given"),
])
def test_a_look_that_does_not_fit_is_one_line(tmp_path, capsys, monkeypatch, argv, part):
    if not SINTEL.exists():
        pytest.skip(f"shared hair data not found at {SINTEL}")
    monkeypatch.chdir(tmp_path)
    out = ["-o", str(tmp_path / ("t" if argv[0] == "turntable" else "x.png"))] if argv[0] != "export-osl" else []
    assert main(argv + out) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and part in err[0], err
    assert not list(tmp_path.iterdir())


@needs_sintel
def test_a_look_preset_that_is_itself_a_groom_is_refused(tmp_path, capsys):
    held = tmp_path / "held.toml"
    held.write_text(f'version = 2\n[scene]\ngenerator = "groom"\ngroom_file = {str(SINTEL)!r}\n')
    assert main(["render", str(HAIR_DATA / "Bangs_100.hair"), "--preset", str(held), "-o",
                 str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err.strip()
    assert "is itself a groom" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "x.png").exists()


@needs_sintel
def test_export_blend_takes_the_look_on_a_groom(tmp_path, monkeypatch, capsys):
    """What export-blend hands the Blender writer (stubbed: bpy takes minutes and is tested on its own in
    tests/export) is the groom under the look, as render has it."""
    from types import SimpleNamespace

    from app.export import blend
    from app.export import blender as B
    from app.presets import resolve_params

    got = {}

    def fake_export(params, out, size, name, progress=None):
        got.update(params=params, name=name)
        return SimpleNamespace(bytes=0, segments=0, guides=0, seconds=0.0, objects=1, neighbour_rows=0,
                               neighbour_cap=0)

    monkeypatch.setattr(blend, "export_blend", fake_export)
    monkeypatch.setattr(B, "_bpy", lambda: None)
    assert main(["export-blend", str(SINTEL), "--preset", LOOK, "-o", str(tmp_path / "s.blend")]) == 0
    assert got["params"] == resolve_params(str(SINTEL), look=LOOK)[0] and got["name"] == "sintel_hair"
