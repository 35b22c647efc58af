#!/usr/bin/env bash
# The main job: set up, then open the lookdev viewer on the default preset if there is a display;
# otherwise render the default preset headless and say where the picture is.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
if [ -n "${DISPLAY:-}${WAYLAND_DISPLAY:-}" ]; then
  exec .venv/bin/vfiber view default
fi
mkdir -p out
.venv/bin/vfiber render default --size 1280x720 -o out/default.png
echo "No display found, so the default preset was rendered headless to: $(pwd)/out/default.png"
