#!/usr/bin/env bash
# Fiber ids of every bundled preset and shared groom (exact and fast, 256x144), one sha256 per image, for
# proving a restructuring changes nothing: run it before and after, then `diff BEFORE/sums AFTER/sums`.
# Usage: scripts/id-sums.sh OUTDIR   (after scripts/setup.sh; grooms are read from ../shared/hair-data)
set -uo pipefail
cd "$(dirname "$0")/.."
out=${1:?usage: scripts/id-sums.sh OUTDIR}
mkdir -p "$out"; : > "$out/sums"
for t in presets/*.toml ../shared/hair-data/*.hair ../shared/hair-data/*.data ../shared/hair-data/*.tfx \
         ../shared/hair-data/*.ply; do
  [ -e "$t" ] || continue
  n=$(basename "$t"); n=${n%.*}
  for mode in exact fast; do
    .venv/bin/vfiber render "$t" --mode "$mode" --output id --size 256x144 --allow-slow \
      -o "$out/$n.$mode.npy" >/dev/null 2>"$out/$n.$mode.err" || echo "FAIL $n $mode" >> "$out/sums"
  done
done
.venv/bin/python - "$out" >> "$out/sums" <<'PY'
import hashlib, pathlib, sys
import numpy as np
for f in sorted(pathlib.Path(sys.argv[1]).glob("*.npy")):
    a = np.load(f)
    print(f.name, hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()[:16], a.shape)
PY
cat "$out/sums"
