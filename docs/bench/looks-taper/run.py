"""Tip taper in the looks suite: python docs/bench/looks-taper/run.py docs/bench/looks-taper [reference tip_taper].

Renders the five shared grooms before / with tip taper / with tip taper and length jitter 0.5 against the
strand reference (app/bench/strand_reference.py); writes the sheets (reference t = 0 only) and rows_t<T>.json.
"""
import sys, json, time
sys.path.insert(0, '.')
from pathlib import Path
from app.gl.context import create_headless
from app.bench.suites import Env
from app.bench import looks
out = Path(sys.argv[1]); out.mkdir(parents=True, exist_ok=True)
t = float(sys.argv[2]) if len(sys.argv) > 2 else 0.0
hc = create_headless()
env = Env(hc.ctx, out=str(out) if t == 0 else None)
variants = {"before": [], "tip taper": ["strand.tip_width=0", "strand.taper_start=0.4"],
            "tip taper, length jitter 0.5": ["strand.tip_width=0", "strand.taper_start=0.4", "fibers.length_jitter=0.5"]}
rows = []
for cfg in looks.configs("full"):
    cfg = {**cfg, "tip_taper": t}
    t0 = time.time()
    r = looks.run(env, cfg, variants)
    rows += r
    for x in r:
        print(x["groom"], x["variant"], x.get("iou"), x.get("orientation_deg"), x.get("covered_virtual"), x.get("luma_virtual"), x.get("ms"), flush=True)
(out / f"rows_t{t}.json").write_text(json.dumps(rows, indent=1))
