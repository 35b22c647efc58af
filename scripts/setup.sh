#!/usr/bin/env bash
# Set up vfiber on Debian 12: the system packages it needs (only those missing), then a virtual
# environment in .venv with vfiber installed in editable mode. Safe to run again; it only adds what is
# missing. Usage: scripts/setup.sh [EXTRAS]   (EXTRAS e.g. "test,bench,blender")
set -euo pipefail
cd "$(dirname "$0")/.."
extras="${1:-}"

# EGL/Mesa for offscreen GL (llvmpipe), OSMesa as the fallback, Xvfb for the viewer without a display,
# glslang for shader linting, python3-venv for the environment.
packages=(python3 python3-venv python3-pip libegl1 libegl-mesa0 libgl1-mesa-dri libgl1 libosmesa6
          xvfb xauth glslang-tools)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing Debian packages: ${missing[*]}"
  sudo=""; [ "$(id -u)" -ne 0 ] && sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${missing[@]}" >/dev/null
fi

# Debian's own Python 3.11 (bpy, the Blender extra, needs exactly 3.11).
python=/usr/bin/python3
if [ ! -x .venv/bin/python ]; then
  echo "setup: creating .venv"
  "$python" -m venv .venv
fi
.venv/bin/python -m pip install -q --upgrade pip
spec="."
[ -n "$extras" ] && spec=".[$extras]"
echo "setup: installing vfiber${extras:+ with $extras}"
.venv/bin/python -m pip install -q -e "$spec"
