"""``python -m tests.hostile``: run the corpus and print the docs/limits.md table (and any failures)."""

import sys
import tempfile
from pathlib import Path

from .corpus import run_corpus, table

with tempfile.TemporaryDirectory() as tmp:
    results = run_corpus(Path(tmp))
print(table(results))
bad = [r for r in results if r.outcome not in ("clean error", "ok")]
for r in bad:
    print(f"FAIL {r.case.boundary} / {r.case.name}: {r.outcome} (rc {r.rc}) {r.stderr[-300:]!r}", file=sys.stderr)
sys.exit(1 if bad else 0)
