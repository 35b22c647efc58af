"""Text from people (preset names, descriptions, labels, help) made safe to put into generated OSL.

OSL source goes through a C preprocessor before it is compiled. That preprocessor ends a line at LF *or*
CR, splices a line that ends in a backslash onto the next one, and reads ``??X`` as a trigraph. So an
escape that handles only ``\\``, ``"`` and ``\\n`` lets a file name such as ``x\\<CR>" ]]<CR>#define ...``
close its string and inject code. Every piece of user text therefore goes through one of these:

* :func:`osl_string_literal`: a complete, double-quoted literal. Printable ASCII stays as it is; ``\\`` and
  ``"`` are escaped; any ``?`` that follows a ``?`` is written ``\\077`` (no trigraph can form); every other
  printable character is written as octal escapes of its UTF-8 bytes (OSL decodes those, so ``é`` reads
  back as ``é``); control and format characters (CR, LF, NUL, tab, U+2028, bidi overrides...) become ``?``
  or a space. The result holds only printable ASCII, so nothing can end the line or the string early.
* :func:`osl_identifier`: a valid OSL identifier that is not a keyword.
* :func:`osl_comment`: one line of text for after ``//`` that cannot end in a line splice.
"""

from __future__ import annotations

import re
import unicodedata

__all__ = ["osl_string_literal", "osl_identifier", "osl_comment"]

_PRINTABLE = {chr(c) for c in range(0x20, 0x7F)}
_WHITESPACE = {"\t", "\n", "\r", "\v", "\f"}

# OSL's reserved words and type names (the language spec, chapter 5, and the words it reserves); an
# identifier equal to one of them gets a trailing underscore.
# OSL's keywords and reserved words, and the shader globals (P, N, I, ...): a parameter or shader named
# like a global would shadow it inside the generated source.
_RESERVED = frozenset("""P I N Ng u v dPdu dPdv dPdx dPdy dPdz time dtime dPdtime Ps Ci

and break closure color continue do else emit float for if illuminance illuminate int matrix normal not or
output point public return string struct vector void while shader surface displacement light volume
bool case catch char class const delete default double enum extern false friend goto inline long new
operator private protected short signed sizeof static switch template this throw true try typedef uniform
union unsigned varying virtual volatile
""".split())


def _visible(ch: str) -> str:
    """One character as text that is safe in a literal (before escaping) or '?' / ' ' if it is not text."""
    if ch in _PRINTABLE:
        return ch
    if ch in _WHITESPACE:
        return " "
    category = unicodedata.category(ch)
    if category[0] == "C" or category in ("Zl", "Zp"):  # control, format, surrogate, unassigned, separators
        return "?"
    return ch


def osl_string_literal(text: str) -> str:
    """``text`` as a complete, quoted OSL string literal that no input can leave (see the module notes)."""
    out = ['"']
    previous = ""
    for ch in str(text):
        ch = _visible(ch)
        if ch == "\\":
            out.append("\\\\")
        elif ch == '"':
            out.append('\\"')
        elif ch == "?":
            out.append("\\077" if previous == "?" else "?")
        elif ch in _PRINTABLE:
            out.append(ch)
        else:  # printable non-ASCII: its UTF-8 bytes as octal escapes, which OSL decodes back
            out.append("".join(f"\\{b:03o}" for b in ch.encode("utf-8")))
        previous = ch
    out.append('"')
    return "".join(out)


def osl_identifier(text: str) -> str:
    """A valid OSL identifier made from ``text``: ASCII letters, digits and ``_`` kept, anything else turned
    into ``_``; never empty, never starting with a digit or ``__`` (reserved), never a keyword."""
    ident = re.sub(r"[^0-9A-Za-z_]", "_", str(text))
    ident = re.sub(r"_{2,}", "_", ident).strip("_")[:64].rstrip("_")
    if not ident:
        return "unnamed"
    if ident[0].isdigit():
        ident = "n" + ident
    if ident in _RESERVED:
        ident += "_"
    return ident


def osl_comment(text: str) -> str:
    """``text`` as one line of printable ASCII for after ``//``: no line break, no trigraph, and no
    trailing backslash (which would splice the next line of source into the comment)."""
    line = "".join(c if c in _PRINTABLE else ("?" if _visible(c) != " " else " ") for c in str(text))
    while "??" in line:
        line = line.replace("??", "? ?")
    line = line.rstrip()
    return line + "." if line.endswith("\\") else line
