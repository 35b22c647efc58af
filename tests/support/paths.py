"""Where the tests find things, wherever a test file sits in tests/."""

from __future__ import annotations

from pathlib import Path

TESTS = Path(__file__).resolve().parents[1]
ROOT = TESTS.parent
HAIR_DATA = ROOT.parent / "shared" / "hair-data"     # the five shared grooms, read in place
GOLDENS = TESTS / "goldens"
FAILURES = TESTS / "_failures"
GLSL_HARNESS = TESTS / "glsl_harness"
GLSL_FIXTURES = TESTS / "glsl_fixtures"
OSL_FIXTURES = TESTS / "osl_fixtures"
