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
    assert info_bytes == 59_207_040   # 1,368 segments x 3,600 fibers x 12 B + 1,368 rows x 80 B (56.5 MiB)


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
