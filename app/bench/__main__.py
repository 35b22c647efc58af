"""``python -m app.bench [suite ...] [--quick] [--out DIR]``: run the benchmark suites.

Suites: memory, rings, containers, accuracy, scaling, grooms, looks (default: all). Each writes DIR/<suite>.csv,
DIR/<suite>.md and DIR/<suite>.png; DIR/summary.md holds the machine, the command and the targets.
``--quick`` runs a reduced set in under two minutes on a 2-core llvmpipe machine (CI, newcomers); the full
set takes under thirty. ``main(argv)`` is what ``vfiber bench`` calls.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shlex
import subprocess
import sys
import time
from pathlib import Path

from ..units import parse_bytes
from .suites import SUITES, Env

ISOLATED_TIMEOUT_S = 1800


def build_parser() -> argparse.ArgumentParser:
    from ..render.explicit import DEFAULT_BUDGET_BYTES

    ap = argparse.ArgumentParser(prog="vfiber bench", description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("suites", nargs="*", metavar="suite",
                    help=f"any of {', '.join(SUITES)} (default: all)")
    level = ap.add_mutually_exclusive_group()
    level.add_argument("--quick", action="store_true", help="reduced set, under two minutes (CI, newcomers)")
    level.add_argument("--smoke", action="store_true", help="one tiny configuration per suite (the tests)")
    ap.add_argument("--out", type=Path, default=None,
                    help="output folder (default out/bench, or out/bench-quick with --quick)")
    ap.add_argument("--reps", type=int, default=10, help="timed frames per measurement (median; default 10)")
    ap.add_argument("--warmup", type=int, default=2, help="untimed frames first (default 2)")
    ap.add_argument("--explicit-budget", type=parse_bytes, default=DEFAULT_BUDGET_BYTES, metavar="BYTES",
                    help="GPU bytes the explicit method may allocate before it refuses (default 1GiB)")
    ap.add_argument("--no-isolate", action="store_true",
                    help="run the memory suite in this process (faster; peak RSS then accumulates)")
    ap.add_argument("--replot", action="store_true", help="redraw tables and plots from the CSVs in --out")
    ap.add_argument("--list", action="store_true", help="list the suites and exit")
    return ap


# Reports with their own command lines: `vfiber bench extremes ...`, `vfiber bench quality ...`,
# `vfiber bench grooms-sheet ...`, `vfiber bench antialias ...`, `vfiber bench highlights ...`
DELEGATED = {"extremes": "app.bench.extremes", "quality": "app.bench.quality",
             "grooms-sheet": "app.bench.grooms", "antialias": "app.bench.antialias",
             "highlights": "app.bench.highlights"}


def main(argv: list[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    if args and args[0] in DELEGATED:
        import importlib

        return importlib.import_module(DELEGATED[args[0]]).main(args[1:])
    try:
        return _main(argv)
    finally:
        # the context made here became the current one; releasing it gives the caller's back
        while _HC:
            _HC.pop().release()


def _main(argv: list[str] | None) -> int:
    args = build_parser().parse_args(argv)
    if args.list:
        for s in SUITES.values():
            print(f"{s.name:11s} {s.title} (thesis: {s.thesis})")
        import importlib
        for name, module in DELEGATED.items():   # reports with their own options: vfiber bench NAME --help
            doc = (importlib.import_module(module).__doc__ or "").strip().splitlines()
            title = re.sub(r"^``[^`]*``:\s*", "", doc[0] if doc else "").rstrip(".")
            print(f"{name:11s} {title} (own options: vfiber bench {name} --help)")
        return 0
    unknown = [s for s in args.suites if s not in SUITES and s != "all"]
    if unknown:
        print(f"vfiber bench: unknown suite {', '.join(map(repr, unknown))}: choose from {', '.join(SUITES)}",
              file=sys.stderr)
        return 2
    if args.reps < 1 or args.warmup < 0:
        print("vfiber bench: --reps must be >= 1 and --warmup >= 0", file=sys.stderr)
        return 2
    names = [s for s in SUITES if not args.suites or "all" in args.suites or s in args.suites]
    level = "smoke" if args.smoke else "quick" if args.quick else "full"
    out = args.out or Path("out") / ("bench" if level == "full" else f"bench-{level}")
    out.mkdir(parents=True, exist_ok=True)
    from . import report
    from .timing import machine_info

    if args.replot:
        machine = _load_machine(out)
        for name in names:
            if (out / f"{name}.csv").exists():
                report.write_suite(name, report.read_csv(out / f"{name}.csv"), out, machine, level)
        return 0

    from tqdm import tqdm

    from .timing import with_gl

    start = time.perf_counter()
    started = machine_info()          # date and commit as the run begins
    jobs = [(name, cfg) for name in names for cfg in SUITES[name].configs(level)]
    env_args = {"reps": args.reps, "warmup": args.warmup, "budget_bytes": args.explicit_budget, "level": level,
                "out": str(out)}
    results: dict[str, list[dict]] = {name: [] for name in names}
    gl = {"renderer": "", "version": ""}
    shared: Env | None = None
    bar = tqdm(jobs, desc="bench", unit="config", dynamic_ncols=True)
    for name, cfg in bar:
        bar.set_description(f"{name} {_short(cfg)}")
        suite = SUITES[name]
        try:
            if suite.isolate and not args.no_isolate:
                rows, info = _run_isolated(name, cfg, env_args)
                gl.update({k: v for k, v in info.items() if v})
            else:
                if shared is None:
                    shared, hc = _make_env(env_args)
                    gl.update(renderer=hc.renderer, version=hc.version)
                rows = suite.run(shared, cfg)
        except Exception as exc:  # one failed configuration must not lose the others
            rows = [dict(_flat(cfg), status="error", note=f"{type(exc).__name__}: {exc}"[:300])]
        for r in rows:
            r.setdefault("status", "ok")
        results[name].extend(rows)
    bar.close()
    if not gl["renderer"]:
        _, hc = _make_env(env_args)
        gl.update(renderer=hc.renderer, version=hc.version)
    machine = with_gl(started, gl["renderer"], gl["version"])
    for name in names:
        report.write_suite(name, results[name], out, machine, level)
    command = "python -m app.bench " + " ".join(shlex.quote(a) for a in (argv if argv is not None else sys.argv[1:]))
    summary = report.write_summary(results, out, machine, level, command.strip(), time.perf_counter() - start)
    print(report.targets_markdown(report.targets(results)))
    print(f"\nwrote {out}/ ({', '.join(names)}); summary: {summary}; "
          f"{(time.perf_counter() - start) / 60:.1f} min")
    return 0


_HC: list = []


def _make_env(env_args: dict):
    from ..gl.context import create_headless

    hc = create_headless()
    _HC.append(hc)  # keep the context alive for the run
    return Env(hc.ctx, **env_args), hc


def _run_isolated(name: str, cfg: dict, env_args: dict) -> tuple[list[dict], dict]:
    job = json.dumps({"suite": name, "cfg": cfg, "env": env_args})
    repo = Path(__file__).resolve().parents[2]
    env = dict(os.environ)
    env["PYTHONPATH"] = str(repo) + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    try:
        proc = subprocess.run([sys.executable, "-m", "app.bench.worker"], input=job, capture_output=True,
                              text=True, timeout=ISOLATED_TIMEOUT_S, env=env)
    except subprocess.TimeoutExpired:
        return [dict(_flat(cfg), status="timeout", note=f"over {ISOLATED_TIMEOUT_S} s")], {}
    last = proc.stdout.strip().splitlines()[-1] if proc.stdout.strip() else ""
    try:
        out = json.loads(last)
    except json.JSONDecodeError:
        why = "killed (out of memory?)" if proc.returncode in (-9, 137) else f"exit {proc.returncode}"
        tail = (proc.stderr or "").strip().splitlines()[-1:] or [""]
        return [dict(_flat(cfg), status="crash", note=f"{why}: {tail[0][:200]}")], {}
    if "error" in out:
        return [dict(_flat(cfg), status="error", note=out["error"][:300])], {}
    return out["rows"], {"renderer": out.get("gl_renderer", ""), "version": out.get("gl_version", "")}


def _flat(cfg: dict) -> dict:
    return {k: (f"{v[0]}x{v[1]}" if isinstance(v, (list, tuple)) else v) for k, v in cfg.items()}


def _short(cfg: dict) -> str:
    return " ".join(f"{v}" for k, v in cfg.items() if k not in ("size", "ref_size"))[:40]


def _load_machine(out: Path):
    from .timing import Machine

    try:
        return Machine(**json.loads((out / "machine.json").read_text()))
    except (OSError, TypeError, ValueError):
        return None


if __name__ == "__main__":
    raise SystemExit(main())
