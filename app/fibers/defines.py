"""The model's numbers as preprocessor defines, for the GLSL (``glsl_defines``) and the OSL (``osl_defines``).

The shaders do not spell these numbers: a GLSL program that uses them is compiled with ``glsl_defines()``
(app/render/renderer.py: model_defines; the explicit baseline), and the OSL export puts ``osl_header()`` in
front of the library (app/export/osl_source.py). glsl/common/hash.glsl and glsl/fibers/layout.glsl keep
``#ifndef`` fallbacks only so that a library file compiles alone in a test harness;
tests/fibers/test_model.py holds those fallbacks equal to these values.
"""

from __future__ import annotations

from .hash import CHANNELS
from .limits import MAX_RINGS, MAX_SUB
from .shape import CURL_PATTERNS, DISPLACEMENT_LIMIT, FRIZZ_WIDTH, NOISE_WIDTH, TWIST_PATTERNS


def _codes() -> dict[str, int]:
    return {**{f"TWIST_{k.upper()}": v for k, v in TWIST_PATTERNS.items()},
            **{f"CURL_{k.upper()}": v for k, v in CURL_PATTERNS.items()}}


def _osl_shape() -> dict[str, float]:
    """The displacement limits osl/stages/container.osl scales by (the GL's uniforms come scaled)."""
    return {"FRIZZ_WIDTH": FRIZZ_WIDTH, "NOISE_WIDTH": NOISE_WIDTH, "DISPLACEMENT_LIMIT": DISPLACEMENT_LIMIT}


def glsl_defines() -> dict[str, int | str]:
    """``{name: value}`` for ``ProgramCache.get``: limits and shape codes as ints, channels as uint
    literals (``0u``), the type of the channel arguments of glsl/common/hash.glsl."""
    return {"MAX_RINGS": MAX_RINGS, "MAX_SUB": MAX_SUB, **{k: f"{v}u" for k, v in CHANNELS.items()}, **_codes()}


def osl_defines() -> dict[str, int | float]:
    """The same for OSL, prefixed ``VF_`` (OSL has no namespaces and no uint: channels are ints), and the
    displacement limits (floats) that the OSL's container stage scales the curl, frizz and noise by."""
    return {f"VF_{k}": v for k, v in {"MAX_RINGS": MAX_RINGS, "MAX_SUB": MAX_SUB, **CHANNELS,
                                      **_codes(), **_osl_shape()}.items()}


def osl_header() -> str:
    """``#define`` lines for the OSL library, in a fixed order."""
    return "".join(f"#define {k} {v}\n" for k, v in osl_defines().items())
