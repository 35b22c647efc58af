"""The OSL twin of the GLSL fiber model, read from ``osl/`` (a tree that mirrors ``glsl/`` file by file).

``osl/common/hash.osl`` is the twin of ``glsl/common/hash.glsl``, ``osl/fibers/traverse.osl`` of
``glsl/fibers/traverse.glsl``, and so on: each GLSL function ``name`` of the fiber model has an OSL function
``vf_name`` in the mirrored file, or the OSL file says in a ``// no-twin: name (why)`` line why it has none;
an OSL function with no GLSL twin is listed in an ``// osl-only: vf_name`` line. ``tests/export/test_osl_twins.py``
fails when a function is on neither side, so whoever changes a GLSL function sees which OSL function to
change with it. Differences the language forces are said in each file's header: OSL has no ``vec2`` (pairs
of floats), no ``uint`` (hash.osl), no infinity arithmetic (``x / 0`` is 0), functions cannot read shader
parameters (``VfParams``, and the per-ring numbers the GL gets as uniforms are computed by ``vf_ring``),
and Cycles' fast-math ``asin``/``atan2`` need refining (trig.osl).

The model's numbers (limits, random-number channels, shape codes) are not spelled in ``osl/``: they are
``app.fibers``'s, and every expanded text starts with their ``#define`` lines (``DEFINES``,
``app.fibers.osl_header``), as the GLSL gets them injected by the renderer.

Includes are resolved here (``#include "fibers/layout.osl"``, relative to the ``osl/`` root, each file
once; an include below a file's first code is inlined where it stands, as in the GLSL), so an exported
shader is one self-contained text: a .blend embeds it as an internal text.

API
===

``osl_root() -> Path``                 the packaged ``app.osl`` (pyproject maps it to ``osl/``), else the checkout's
``expand(rel) -> str``                 ``osl/<rel>`` with its includes inlined (each file once)
``DEFINES``                            the ``#define`` section of the model's numbers, first in every text
``LIBRARY``                            the library sections in include order (tuple of str; a file split by
                                       an inlined include is two), for probe shaders
``SHADER_BODY``                        the shader body (``osl/stages/container.osl``), after the parameter block
"""

from __future__ import annotations

import importlib
import re
from pathlib import Path

from ..fibers import osl_header

__all__ = ["osl_root", "expand", "library_files", "DEFINES", "LIBRARY", "SHADER_BODY", "ENTRY", "STAGE"]

#: the files the shader needs, in an order that satisfies their includes
ENTRY = ("fibers/traverse.osl", "stages/segment.osl", "shading/principled_hair.osl")
STAGE = "stages/container.osl"
_INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+\.osl)"\s*$')
_DEFINES_REL = "<app.fibers>"       # the section that is no file: the model's numbers as defines
DEFINES = f"// ==== app/fibers: the model's limits, channels and shape codes ====\n{osl_header()}"


def osl_root() -> Path:
    """The OSL library: the packaged ``app.osl``, else the checkout's ``osl/``."""
    try:
        paths = list(getattr(importlib.import_module("app.osl"), "__path__", []))
        if paths and (Path(paths[0]) / STAGE).is_file():
            return Path(paths[0])
    except (ImportError, TypeError, ValueError):
        pass
    return Path(__file__).resolve().parents[2] / "osl"


def _read(rel: str) -> str:
    path = osl_root() / rel
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise FileNotFoundError(f"osl/{rel}: missing from the OSL library at {osl_root()} "
                                "(reinstall vfiber)") from None


def _sections(entries) -> list[tuple[str, str]]:
    """(file, text) sections in the order the shader needs them, each file once. An include before a
    file's first line of code is a dependency, placed before the file; one further down is inlined where
    it stands, as the GLSL's is (traverse.osl includes shaped.osl after the types and helpers it uses)."""
    sections: list[tuple[str, str]] = [(_DEFINES_REL, DEFINES)]
    done: list[str] = []

    def visit(rel: str, stack: tuple[str, ...]) -> None:
        if rel in done:
            return
        if rel in stack:
            raise ValueError(f"osl/{rel}: include cycle {' -> '.join(stack + (rel,))}")
        chunk: list[str] = []
        code = False                    # whether chunk holds more than comments

        def flush() -> None:
            body = "\n".join(chunk).strip()
            if body:
                later = any(r == rel for r, _ in sections)
                sections.append((rel, f"// ==== osl/{rel}{' (continued)' if later else ''} ====\n{body}\n"))
            chunk.clear()

        for line in _read(rel).splitlines():
            m = _INCLUDE.match(line)
            if not m:
                chunk.append(line)
                code = code or bool(line.strip()) and not line.lstrip().startswith("//")
                continue
            if code:
                flush()
                code = False
            visit(m.group(1), stack + (rel,))
        flush()
        done.append(rel)

    for rel in entries:
        visit(rel, ())
    return sections


def library_files(entries=ENTRY) -> list[str]:
    """The library files in the order they begin in the shader (dependencies first), each once."""
    order: list[str] = []
    for rel, _ in _sections(entries):
        if rel not in order and rel != _DEFINES_REL:
            order.append(rel)
    return order


def expand(rel: str) -> str:
    """``osl/<rel>`` with every include inlined once (dependencies first, later includes in place)."""
    return "\n".join(text for _, text in _sections((rel,)))


LIBRARY: tuple[str, ...] = tuple(text for _, text in _sections(ENTRY))
SHADER_BODY: str = "\n" + "\n".join(line for line in _read(STAGE).splitlines()
                                     if not line.startswith("//")) + "\n"
