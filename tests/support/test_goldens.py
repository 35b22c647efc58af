"""The golden comparison itself: a missing golden fails, a changed picture fails, an equal one passes."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from PIL import Image

from tests.support import goldens

LLVMPIPE = SimpleNamespace(renderer="llvmpipe (LLVM 15.0.6, 256 bits)", version="4.5 (Core Profile) Mesa 22.3.6")


def _img(value: int = 0) -> np.ndarray:
    img = np.zeros((8, 8, 3), np.uint8)
    img[2:6, 2:6] = value
    return img


def test_missing_golden_fails(tmp_path):
    with pytest.raises(pytest.fail.Exception, match="missing"):
        goldens.check_golden(LLVMPIPE, _img(200), tmp_path / "x.png", 0.0, False, "x")


def test_changed_picture_fails_and_equal_passes(tmp_path, monkeypatch):
    monkeypatch.setattr(goldens, "FAILURES", tmp_path / "_failures")
    path = tmp_path / "x.png"
    goldens.check_golden(LLVMPIPE, _img(200), path, 0.0, True, "x")      # --regen-goldens records it
    assert path.exists() and "x" in (tmp_path / "meta.json").read_text()
    goldens.check_golden(LLVMPIPE, _img(200), path, 0.0, False, "x")
    with pytest.raises(pytest.fail.Exception, match="differ"):
        goldens.check_golden(LLVMPIPE, _img(100), path, 0.1, False, "x")
    assert (tmp_path / "_failures" / "x.diff.png").exists()
    Image.open(tmp_path / "_failures" / "x.got.png").verify()
