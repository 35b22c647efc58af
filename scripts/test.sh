#!/usr/bin/env bash
# Set up everything the tests need (Debian packages, venv, the test, bench and blender extras), then run
# every test. Extra arguments go to pytest.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh "test,bench,blender"
exec .venv/bin/python -m pytest "$@"
