"""Golden images: one comparison for every golden test.

A golden is a PNG recorded on llvmpipe next to a meta.json that says which Mesa recorded it. A missing
golden fails: a deleted or never-committed golden must not pass as "recorded a new one". Record or
rewrite goldens on purpose with ``pytest --regen-goldens`` (README, Developing).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

FAILURES = Path(__file__).resolve().parents[1] / "_failures"
LEVELS = 8      # a pixel differs when a channel moves by more than 8/255


def mesa_version(gl) -> str:
    return gl.version.split("Mesa")[-1].strip() if "Mesa" in gl.version else gl.version


def require_llvmpipe(gl) -> None:
    """Goldens are exact on llvmpipe run to run; another driver rounds differently."""
    if "llvmpipe" not in gl.renderer:
        pytest.skip(f"goldens are recorded on llvmpipe; this is {gl.renderer}")


def check_golden(gl, img: np.ndarray, path: Path, tolerance: float, regen: bool, label: str,
                 meta_extra: dict | None = None) -> None:
    """Compare ``img`` (H, W, 3) uint8 with the golden at ``path``; fail with pictures in tests/_failures.

    ``tolerance`` is the fraction of pixels allowed to differ by more than LEVELS/255. With ``regen`` the
    golden and its meta.json entry are rewritten instead.
    """
    require_llvmpipe(gl)
    meta_path = path.parent / "meta.json"
    meta = json.loads(meta_path.read_text()) if meta_path.exists() else {}
    key = path.stem
    if regen:
        path.parent.mkdir(parents=True, exist_ok=True)
        Image.fromarray(img).save(path)
        meta[key] = {"mesa": mesa_version(gl), "renderer": gl.renderer, **(meta_extra or {})}
        meta_path.write_text(json.dumps(meta, indent=2, sort_keys=True) + "\n")
        return
    if not path.exists():
        pytest.fail(f"{label}: golden {path} is missing; record it on purpose with "
                    "`pytest --regen-goldens` and commit it")
    want = np.asarray(Image.open(path).convert("RGB"))
    assert want.shape == img.shape, (f"{label}: golden {path.name} is {want.shape[1]}x{want.shape[0]}, "
                                     f"the render {img.shape[1]}x{img.shape[0]}; run --regen-goldens")
    diff = np.abs(want.astype(int) - img.astype(int)).max(-1)
    bad = (diff > LEVELS).mean()
    if bad > tolerance:
        FAILURES.mkdir(exist_ok=True)
        Image.fromarray(img).save(FAILURES / f"{label}.got.png")
        Image.fromarray(want).save(FAILURES / f"{label}.want.png")
        Image.fromarray(np.clip(diff * 8, 0, 255).astype(np.uint8)).save(FAILURES / f"{label}.diff.png")
        recorded = meta.get(key, {}).get("mesa", "?")
        pytest.fail(f"{label}: {bad:.3%} of pixels differ (recorded on Mesa {recorded}, now "
                    f"{mesa_version(gl)}); see tests/_failures/{label}.*.png, or --regen-goldens "
                    "if the change is intended")
