"""The code passes ruff, and the typed core passes mypy, with the project's configuration (pyproject.toml:
[tool.ruff], [tool.mypy]). The test command is the one place both run, so a lint or type error fails CI like
any other defect."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.support.paths import ROOT


def _tool(name: str) -> list[str]:
    here = Path(sys.executable).with_name(name)
    if here.exists():
        return [str(here)]
    found = shutil.which(name)
    if found:
        return [found]
    pytest.fail(f"{name} is not installed: it is part of the [test] extra (bash scripts/test.sh installs it)")


def test_ruff_is_clean():
    run = subprocess.run([*_tool("ruff"), "check", "--output-format", "concise", "app", "tests"],
                         cwd=ROOT, capture_output=True, text=True)
    assert run.returncode == 0, "ruff found problems (fix them, or `ruff check --fix`):\n" + run.stdout[-6000:]


def test_the_typed_core_passes_mypy():
    run = subprocess.run([*_tool("mypy")], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, "mypy found problems in the typed core:\n" + run.stdout[-6000:]
