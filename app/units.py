"""Sizes for people: one way to print and to read a byte count or an image size everywhere (CLI, viewer,
benches, budget errors)."""

from __future__ import annotations


def human_bytes(n: float) -> str:
    """1023 B, 1.5 KiB, 11.5 MiB ... (binary units, one decimal above bytes)."""
    for unit in ("B", "KiB", "MiB", "GiB"):
        if abs(n) < 1024:
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.1f} TiB"


def parse_bytes(text: str) -> int:
    """'1GiB', '512 MiB', '2e9' or a plain integer of bytes. A bad size raises argparse.ArgumentTypeError,
    which argparse turns into its usage message when this is an option's ``type``."""
    import argparse
    import re

    m = re.fullmatch(r"\s*([0-9.eE+]+)\s*([KMGT]?i?B?)?\s*", text)
    if not m:
        raise argparse.ArgumentTypeError(f"{text!r} is not a size: write e.g. 1GiB, 512MiB or 2000000000")
    unit = (m.group(2) or "").upper().rstrip("B").rstrip("I")
    scale = {"": 1, "K": 2**10, "M": 2**20, "G": 2**30, "T": 2**40}[unit]
    try:
        return int(float(m.group(1)) * scale)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a size") from None


def parse_size(text: str) -> tuple[int, int]:
    """``--size WIDTHxHEIGHT`` in pixels, each 1 .. 16384."""
    from .errors import UsageError

    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise UsageError(f"--size {text!r}: expected WIDTHxHEIGHT, e.g. 640x360") from None
    if not (1 <= w <= 16384 and 1 <= h <= 16384):
        raise UsageError(f"--size {text!r}: width and height must be between 1 and 16384")
    return w, h
