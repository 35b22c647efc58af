"""vfiber bench: the helpers' arithmetic, and one tiny configuration of every suite end to end."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from PIL import Image

from app.bench.__main__ import main, parse_bytes
from app.bench.report import targets
from app.bench.grooms import targets as grooms_targets
from app.bench.suites import SUITES, Env, layout_for, memory_run
from app.bench.timing import Timing, crossover, fit_power_law, time_frames
from app.reference import fiber_count
from app.params import Params


def test_timing_statistics():
    t = Timing([10.0, 12.0, 11.0, 50.0, 9.0])
    assert t.median_ms == 11.0
    mean = np.mean(t.samples_ms)
    assert math.isclose(t.cv, np.std(t.samples_ms, ddof=1) / mean)
    calls = []
    out = time_frames(lambda: calls.append(1), warmup=2, reps=10)
    assert len(calls) == 12 and out.reps == 10 and all(s >= 0 for s in out.samples_ms)


def test_power_law_fit_and_crossover():
    x = np.array([1, 2, 4, 8, 16, 32], float)
    b, a, r2 = fit_power_law(x, 3.0 * x ** 1.5)
    assert math.isclose(b, 1.5, rel_tol=1e-9) and math.isclose(a, 3.0, rel_tol=1e-9) and r2 > 0.999999
    # explicit grows linearly, virtual stays flat at 100: they cross at x = 100
    xs = [10, 100 / 3, 1000]
    assert math.isclose(crossover(xs, [x for x in xs], [100, 100, 100]), 100.0, rel_tol=1e-9)
    assert crossover([1, 10], [1, 2], [5, 6]) is None


@pytest.mark.parametrize("text,expected", [("1GiB", 2**30), ("512 MiB", 512 * 2**20), ("2e9", 2_000_000_000),
                                           ("1000", 1000), ("1.5G", int(1.5 * 2**30))])
def test_parse_bytes(text, expected):
    assert parse_bytes(text) == expected


@pytest.mark.parametrize("per", [10, 1000, 100_000, 1_000_000])
def test_layout_hits_the_fiber_count(per):
    p = Params(layout_for(per))
    _, exact = fiber_count(p)
    assert abs(exact - per) <= 0.01 * per + p["fibers.rings"]


def test_over_budget_is_a_row_not_a_crash(ctx):
    env = Env(ctx, reps=1, warmup=0, budget_bytes=1000, level="smoke")
    cfg = SUITES["memory"].configs("smoke")[1]
    assert cfg["method"] == "explicit"
    [row] = memory_run(env, cfg)
    assert row["status"] == "refused" and row["needed_bytes"] > 1000 and "budget" in row["note"]


def test_unknown_suite(capsys):
    assert main(["nonsense", "--smoke"]) == 2
    assert "unknown suite" in capsys.readouterr().err


def test_smoke_run_writes_every_suite(tmp_path):
    """One tiny configuration of each suite: CSV, Markdown table and PNG plot, machine and targets."""
    out = tmp_path / "bench"
    assert main(["--smoke", "--reps", "2", "--warmup", "1", "--out", str(out)]) == 0
    for name in SUITES:
        with open(out / f"{name}.csv", newline="") as f:
            rows = list(csv.DictReader(f))
        assert rows, name
        assert all(r["status"] == "ok" for r in rows), (name, [r.get("note") for r in rows])
        assert all(float(r["ms"]) > 0 for r in rows), name
        md = (out / f"{name}.md").read_text()
        assert "| ms/frame |" in md.replace("ms/frame | CV", "ms/frame |") or "ms/frame" in md
        assert "llvmpipe" in md or "renderer:" in md
        with Image.open(out / f"{name}.png") as img:
            assert img.size[0] > 300 and img.size[1] > 200
    machine = json.loads((out / "machine.json").read_text())
    assert machine["gl_renderer"] and machine["commit"]
    summary = (out / "summary.md").read_text()
    assert "## Targets" in summary and "python -m app.bench" in summary
    # the memory rows carry exact buffer bytes and a peak RSS from their own process
    with open(out / "memory.csv", newline="") as f:
        mem = {r["method"]: r for r in csv.DictReader(f)}
    assert int(mem["virtual"]["gpu_bytes"]) < int(mem["explicit"]["gpu_bytes"])
    assert int(mem["explicit"]["rss_peak"]) > 0 and float(mem["explicit"]["coverage_agree"]) > 0.98
    # tables and plots can be redrawn from the CSVs alone
    (out / "memory.png").unlink()
    assert main(["memory", "--smoke", "--replot", "--out", str(out)]) == 0
    assert (out / "memory.png").exists()


def test_targets_from_rows():
    mem = [{"method": "virtual", "fibers": 10**6, "gpu_bytes": 8432, "ms": 50.0, "fast_ms": 40.0, "status": "ok"},
           {"method": "explicit", "fibers": 10**6, "gpu_bytes": 12_003_600, "ms": 900.0, "status": "ok"},
           {"method": "virtual", "fibers": 10**3, "gpu_bytes": 8432, "ms": 45.0, "status": "ok"},
           {"method": "explicit", "fibers": 10**3, "gpu_bytes": 15600, "ms": 5.0, "status": "ok"}]
    acc = [{"mode": "exact", "shape": "straight", "fibers_per_container": 3600, "tests_per_px": 20.0,
            "tests_vs_brute": 300.0, "differ_brute_px": 0}]
    got = {r["target"]: r for r in targets({"memory": mem, "accuracy": acc})}
    met = [r["met"] for r in got.values() if r["met"] is not None]
    assert all(met) and len(met) == 4
    cross = next(r for k, r in got.items() if k.startswith("cross-over"))
    assert "fibers" in cross["measured"]


def test_grooms_targets_from_rows():
    """Issue 12's targets read the right rows: harolongo against the default preset, Table 4's largest
    scene against its smallest; the two time ratios are judged on CPU time (the wall clock is reported)."""
    rows = [{"scene": "default preset", "ms": 20.0, "cpu_ms": 30.0, "status": "ok"},
            {"scene": "harolongo.data", "ms": 70.0, "cpu_ms": 60.0, "x_ms": 3.5, "x_cpu_ms": 2.0, "width": 640,
             "height": 360, "entered_per_px": 1.9, "candidates_per_px": 2.1, "tests_per_px": 41.0},
            {"scene": "Table 4 full, 10 containers", "segments": 10, "us_per_covered_px": 5.0,
             "cpu_us_per_covered_px": 4.0, "x_us_per_covered_px": 1.0, "x_cpu_us_per_covered_px": 1.0},
            {"scene": "Table 4 full, 200 containers", "segments": 200, "us_per_covered_px": 9.0,
             "cpu_us_per_covered_px": 8.8, "x_us_per_covered_px": 1.8, "x_cpu_us_per_covered_px": 2.2}]
    got = grooms_targets(rows)
    assert [r["target"][:12] for r in got] == ["harolongo pe", "harolongo: c", "harolongo: f", "Table 4 full"]
    met = [r["met"] for r in got]
    assert met == [True, True, False, False]            # frame 2.0x CPU; entered 1.9; tests 41; Table 4 2.2x CPU
    assert "3.50x wall" in got[0]["measured"] and "1.80x wall" in got[3]["measured"]


def test_shape_grooms_section_measures_each_shape_against_the_groom_straight(gl, monkeypatch, tmp_path):
    """The quality bench's shape-grooms section on one shared groom (the quickest to render, at a small size): a row
    per shape with its ratio to the same groom's straight frame, and one fiber range each."""
    import app.bench.grooms as grooms
    from app.bench.quality import Bench, shape_grooms_section

    if not (grooms.HAIR_DATA / "Ratboy_mohawk.tfx").exists():
        pytest.skip("the shared grooms are not here")
    monkeypatch.setattr(grooms, "GROOM_FILES", ("Ratboy_mohawk.tfx",))

    class Bar:
        def update(self):
            pass

    b = Bench(reps=1, gl=gl)          # the session's context: a second one would stay current after the test
    rows = shape_grooms_section(b, (96, 54), tmp_path, Bar())
    assert [r["shape"] for r in rows] == ["straight", "curled", "twisted", "combined"]
    assert rows[0]["cpu_vs_straight"] == 1.0 and all(r["cpu_ms"] > 0 for r in rows)
    assert all(r["tests_per_px"] > 0 and r["ranges"] == 1 for r in rows)
    assert {r["groom"] for r in rows} == {"Ratboy_mohawk.tfx"} and rows[0]["segments"] > 1000
