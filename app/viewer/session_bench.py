"""A scripted viewer session on a big groom that measures what a person waits for (issue 12).

    python -m app.viewer.session_bench [GROOM] [--size 1280x720] [--out DIR] [--frames N] [--skip-whole]

It starts ``vfiber view GROOM --script ...`` under ``xvfb-run -a`` and reads the console as it comes,
timestamped from the moment the process was started:

* window up, scene built, first picture (any part of it: the sketch, the first strips), first complete
  frame (the viewer's own console lines);
* the median UI frame while the final frame refines in strips (script ``bench quality = "refining"``),
  and the same while an orbit drag refines its interactive frames;
* how long a click on the File menu takes to open it while the frame refines (wall clock from the click
  to the grab that shows the menu);
* the median whole interactive and final frames (``bench quality = "interactive"`` / ``"final"``: one
  forced, unstripped render per UI frame), the numbers the renderer decides; ``--skip-whole`` leaves
  them out (they take ~10 s a frame on llvmpipe with the per-strand harolongo).

Grabs of the window (UI included) land in DIR with a ``session.json`` of every figure; the lead reruns
this after a renderer change and compares. Timings are noisy on a shared machine: quote the load.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HAROLONGO = Path(__file__).resolve().parents[2] / ".." / "shared" / "hair-data" / "harolongo.data"
PREFIX = "vfiber-script: "
CONSOLE = {
    "window_up_s": re.compile(r"window up ([\d.]+) s after start"),
    "first_picture_s": re.compile(r"first picture ([\d.]+) s after start"),
    "first_complete_s": re.compile(r"first complete frame ([\d.]+) s after start"),
    "scene_build_s": re.compile(r"container segments in ([\d.]+) s"),
}
FILE_MENU = (28, 10)          # the File menu's title in the main menu bar (window coordinates)


def session_steps(out: Path, frames: int, whole: bool) -> list[dict]:
    steps: list[dict] = [
        {"wait": 1},                                                  # steps wait while the scene loads
        {"grab": str(out / "first.png"), "ui": True},                 # the first frames with the scene
        {"bench": frames, "quality": "refining", "timeout": 300},     # UI frames while the final refines
        {"echo": "click File"},
        {"mouse": [list(FILE_MENU), list(FILE_MENU) + ["down"], list(FILE_MENU) + ["up"]]},
        {"grab": str(out / "menu.png"), "ui": True},
        {"echo": "menu shown"},
        {"mouse": [list(FILE_MENU), list(FILE_MENU) + ["down"], list(FILE_MENU) + ["up"]]},   # closes it
        {"print": "refining"},
        {"wait_final": True},
        {"grab": str(out / "final.png"), "ui": True},
        {"wait_for": "tests_per_pixel", "timeout": 600},             # the overlay's cost render, in strips
        {"bench": 10, "quality": "ui"},                              # UI frames with nothing to render
        {"drag": [60, 0], "button": "left"},                        # an orbit: interactive frames refine
        {"bench": max(frames // 2, 3), "quality": "refining", "timeout": 300},
        {"grab": str(out / "orbit.png"), "ui": True},
    ]
    if whole:
        steps += [{"bench": 3, "quality": "interactive"}, {"bench": 2, "quality": "final"}]
    steps += [{"print": "report"}, {"quit": 0}]
    return steps


def run_session(groom: Path, size: tuple[int, int], out: Path, frames: int, whole: bool,
                timeout_s: float = 1200.0) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    script = {"size": list(size), "steps": session_steps(out, frames, whole)}
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
        json.dump(script, f)
        script_path = f.name
    xvfb = shutil.which("xvfb-run")
    if xvfb is None:
        raise SystemExit("session_bench: xvfb-run not found (apt-get install xvfb xauth)")
    cmd = [xvfb, "-a", "-s", f"-screen 0 {size[0] + 64}x{size[1] + 64}x24", sys.executable, "-m", "app.viewer.app",
           str(groom), "--script", script_path]
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1,
                            env={**os.environ, "PYTHONUNBUFFERED": "1"})
    result: dict = {"groom": str(groom), "size": list(size), "benches": [], "console": []}
    marks: dict[str, float] = {}
    try:
        assert proc.stdout is not None
        for line in proc.stdout:
            t = time.perf_counter() - t0
            line = line.rstrip("\n")
            if time.perf_counter() - t0 > timeout_s:
                proc.kill()
                raise SystemExit(f"session_bench: no end after {timeout_s:.0f} s")
            if line.startswith(PREFIX):
                msg = json.loads(line[len(PREFIX):])
                if "bench" in msg:
                    result["benches"].append(msg["bench"])
                elif "echo" in msg:
                    marks[msg["echo"]] = t
                elif "grab" in msg:
                    marks[f"grab {Path(msg['grab']).name}"] = t
                elif "report" in msg:
                    result["stats"] = msg["report"]["stats"]
                elif "refining" in msg:
                    result["refining_at_menu"] = msg["refining"]
                continue
            result["console"].append(f"{t:7.2f} s  {line}")
            for name, rx in CONSOLE.items():
                m = rx.search(line)
                if m and name not in result:
                    result[name] = float(m.group(1))          # the viewer's clock (from its import)
                    result[name.replace("_s", "_from_spawn_s")] = t   # this one: from the process start
        rc = proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
        os.unlink(script_path)
    result["exit_code"] = rc
    result["marks_s"] = marks
    if "click File" in marks and "grab menu.png" in marks:
        result["menu_open_s"] = marks["grab menu.png"] - marks["click File"]
    names = ["refining_final", "ui_only", "refining_orbit"] + (["interactive", "final"] if whole else [])
    for name, bench in zip(names, result["benches"]):
        result[f"{name}_frame_ms_median"] = bench.get("frame_ms_median")
        if name.startswith("refining"):
            result[f"{name}_fibers_ms_median"] = bench.get("fibers_ms_median")
        result[f"{name}_frames"] = bench.get("frames")
    (out / "session.json").write_text(json.dumps(result, indent=2), encoding="utf-8")
    return result


def contact_sheet(rows: list[tuple[str, list[tuple[Path, str]]]], out: Path, width: int = 480) -> None:
    """Grabs side by side, a caption under each and a title over each row (PIL only)."""
    from PIL import Image, ImageDraw

    cells = [[(Image.open(p).convert("RGB"), caption) for p, caption in row if Path(p).is_file()] for _, row in rows]
    ncol = max((len(r) for r in cells), default=1)
    scale = width / max((im.width for r in cells for im, _ in r), default=width)
    cell_h = int(max((im.height for r in cells for im, _ in r), default=270) * scale)
    title_h, cap_h, pad = 22, 34, 8
    sheet = Image.new("RGB", (ncol * (width + pad) + pad, len(rows) * (title_h + cell_h + cap_h) + pad), (24, 24, 26))
    draw = ImageDraw.Draw(sheet)
    y = pad
    for (title, _), row in zip(rows, cells):
        draw.text((pad, y + 4), title, fill=(235, 235, 235))
        y += title_h
        for i, (im, caption) in enumerate(row):
            x = pad + i * (width + pad)
            sheet.paste(im.resize((width, int(im.height * scale))), (x, y))
            for j, text in enumerate(caption.split("\n")[:2]):
                draw.text((x, y + cell_h + 3 + 14 * j), text, fill=(200, 200, 200))
        y += cell_h + cap_h
    out.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(out)


def _size(text: str) -> tuple[int, int]:
    w, h = (int(x) for x in text.lower().split("x"))
    return w, h


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m app.viewer.session_bench", description=__doc__.split("\n")[0])
    ap.add_argument("groom", nargs="?", default=str(HAROLONGO.resolve()), help="groom file (default harolongo)")
    ap.add_argument("--size", type=_size, default=(1280, 720))
    ap.add_argument("--out", default="docs/viewer/session", help="where the grabs and session.json go")
    ap.add_argument("--frames", type=int, default=20, help="UI frames to time while refining")
    ap.add_argument("--skip-whole", action="store_true", help="skip the forced whole interactive/final frames")
    args = ap.parse_args(argv)
    r = run_session(Path(args.groom), args.size, Path(args.out), args.frames, not args.skip_whole)
    keys = ["window_up_from_spawn_s", "scene_build_s", "first_picture_from_spawn_s", "first_complete_from_spawn_s",
            "menu_open_s",
            "refining_final_frame_ms_median", "refining_final_fibers_ms_median", "ui_only_frame_ms_median",
            "refining_orbit_frame_ms_median", "refining_orbit_fibers_ms_median",
            "interactive_frame_ms_median",
            "final_frame_ms_median"]
    load = os.getloadavg()[0]
    print(f"{Path(args.groom).name} at {args.size[0]}x{args.size[1]} (load {load:.1f}, {os.cpu_count()} CPUs):")
    for k in keys:
        if k in r and r[k] is not None:
            print(f"  {k:34s} {r[k]:10.2f}")
    print(f"  exit code {r['exit_code']}; grabs and session.json in {args.out}")
    return 0 if r["exit_code"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
