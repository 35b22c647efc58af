"""Sizes for people: one way to print a byte count everywhere (CLI, viewer, benches, budget errors)."""

from __future__ import annotations


def human_bytes(n: float) -> str:
    """1023 B, 1.5 KiB, 11.5 MiB ... (binary units, one decimal above bytes)."""
    for unit in ("B", "KiB", "MiB", "GiB"):
        if abs(n) < 1024:
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.1f} TiB"
