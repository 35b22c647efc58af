"""Text into OSL source, safely: string literals and identifiers.

``osl_string_literal(text) -> str``
    The complete double-quoted OSL literal whose value is ``text``. Backslashes and quotes are escaped,
    CR, LF and tab become ``\\r``, ``\\n``, ``\\t``, other control characters octal escapes; NUL is
    removed (it would cut the string short in the compiled shader). A ``?`` that follows
    a ``?`` is written ``\\077`` (octal) so no trigraph (``??=`` is ``#``, ``??/`` a backslash to a preprocessor that
    honours trigraphs) can form. Nothing in ``text`` can end the literal or the line it is on.
``osl_identifier(text) -> str``
    A valid OSL identifier made from ``text``: characters outside ``[A-Za-z0-9_]`` become ``_``, a leading
    digit gets a ``_`` before it, and a keyword, reserved word or shader global (``P``, ``N``, ``u``...)
    gets a ``_`` after it. The empty string gives ``_``.
"""

from __future__ import annotations

import re

__all__ = ["osl_string_literal", "osl_identifier", "RESERVED"]

_ESCAPES = {"\\": "\\\\", '"': '\\"', "\n": "\\n", "\r": "\\r", "\t": "\\t"}

#: OSL keywords, reserved words (OSL spec 5.1) and shader globals a parameter must not shadow
RESERVED = frozenset("""
and break closure color continue do else emit float for if illuminance illuminate int matrix normal not or
output point public return string struct vector void while
bool case catch char class const delete default double enum extern false friend goto inline long new operator
private protected short signed sizeof static switch template this throw true try typedef uniform union
unsigned varying virtual volatile
P I N Ng u v dPdu dPdv Ps time dtime dPdtime Ci L Cl Os
""".split())


def osl_string_literal(text: str) -> str:
    out = []
    prev = ""
    for ch in str(text):
        if ch in _ESCAPES:
            out.append(_ESCAPES[ch])
        elif ch == "\0":
            pass                                    # a NUL would cut the string short in the shader
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\{ord(ch):03o}")          # other control characters, as octal escapes
        elif ch == "?" and prev == "?":
            out.append("\\077")                     # "?" in octal: no trigraph can form
        else:
            out.append(ch)
        prev = ch
    return '"' + "".join(out) + '"'


def osl_identifier(text: str) -> str:
    ident = re.sub(r"[^0-9A-Za-z_]", "_", str(text))
    if not ident:
        return "_"
    if ident[0].isdigit():
        ident = "_" + ident
    if ident in RESERVED:
        ident += "_"
    return ident
