"""Run one benchmark configuration in this (fresh) process: ``python -m app.bench.worker`` reads
``{"suite", "cfg", "env"}`` as JSON on stdin and prints ``{"rows": [...]}`` as the last stdout line.

A fresh process per configuration is what makes a peak resident set size (ru_maxrss never goes down)
belong to that configuration alone.
"""

from __future__ import annotations

import json
import sys
import traceback


def main() -> int:
    job = json.loads(sys.stdin.read())
    try:
        from ..gl.context import create_headless
        from .suites import SUITES, Env

        hc = create_headless()
        env = Env(hc.ctx, **job["env"])
        rows = SUITES[job["suite"]].run(env, job["cfg"])
        out = {"rows": rows, "gl_renderer": hc.renderer, "gl_version": hc.version}
    except Exception as exc:  # reported as a row by the parent, never a silent hole in a table
        out = {"error": f"{type(exc).__name__}: {exc}", "trace": traceback.format_exc()[-2000:]}
    sys.stdout.write("\n" + json.dumps(out, default=float) + "\n")
    sys.stdout.flush()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
