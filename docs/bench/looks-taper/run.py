"""Tip taper in the looks suite: ``python docs/bench/looks-taper/run.py docs/bench/looks-taper``.

Renders the five shared grooms before / with tip taper / with tip taper and length jitter 0.5 against the
suite's own reference (app/bench/strand_reference.py, interpolated children) at 640x360; writes the sheets
and rows.json into the folder given.
"""
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[3]))
from app.bench import looks  # noqa: E402
from app.bench.suites import Env  # noqa: E402
from app.gl.context import create_headless  # noqa: E402

# measured on the plain fill, the groom defaults of the time (looks.REFERENCE_SETS: groom_auto off)
PLAIN = list(looks.REFERENCE_SETS)
VARIANTS = {"before": PLAIN, "tip taper": PLAIN + ["strand.tip_width=0", "strand.taper_start=0.4"],
            "tip taper, length jitter 0.5": PLAIN + ["strand.tip_width=0", "strand.taper_start=0.4",
                                                     "fibers.length_jitter=0.5"]}

out = Path(sys.argv[1])
out.mkdir(parents=True, exist_ok=True)
env = Env(create_headless().ctx, out=str(out))
rows = []
for cfg in looks.configs("full"):
    t0 = time.time()
    for r in looks.run(env, {**cfg, "references": (looks.REFERENCE,)}, VARIANTS):
        rows.append(r)
        print(r["groom"], "|", r["variant"], "|", r.get("iou"), r.get("orientation_deg"), r.get("covered_virtual"),
              r.get("luma_virtual"), f"{time.time() - t0:.0f} s", flush=True)
(out / "rows.json").write_text(json.dumps(rows, indent=1))
