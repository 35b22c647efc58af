"""Hostile input at every boundary: each finding of the hostile-input run (issue 18) as a regression test,
the corpus in tests/hostile/ run through the command line, and property-based fuzzing (hypothesis).

Every case must end in a clean one-line error (or a correct result): no traceback, no hang, no crash, no
wrong acceptance, no lost file. ``python -m tests.hostile`` prints the docs/limits.md table from the corpus.
"""

from __future__ import annotations

import importlib.util
import os
import re
import stat
import subprocess
import sys
import warnings
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from app.export import osl as X
from app.export.osl_strings import osl_comment, osl_identifier, osl_string_literal
from app.params import Params

HAVE_BPY = importlib.util.find_spec("bpy") is not None
ROOT = Path(__file__).resolve().parents[1]
FUZZ = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])

# The OSL injection of the hostile run: a backslash + CR splices the line, the quote closes the label and
# the #define line is compiled, turning every transparent() into emission().
INJECTION = 'x\\\r" ]]\r#define transparent emission\r//'
HOSTILE_NAMES = [INJECTION, "a??=b", "a??/\nb", "bare\rcr", "nul\0byte", "tab\tand\nlf", 'quote"', "back\\",
                 "\\", "??", "???=", "\u2028line\u2029para", "\u202eevil", "\ud800lone", "é ü 中文 😀",
                 "*/ /* // #include \"x\"", "\x7f\x85\x9b", "x" * 3000, "", "123", "default", "int"]


# --------------------------------------------------------------------------------------------------
# 1. OSL export: strings and identifiers no input can leave

def _decode_osl_literal(lit: str) -> str:
    """What OSL reads from a literal made by osl_string_literal (escapes \\\\, \\" and \\ooo)."""
    assert lit[0] == lit[-1] == '"'
    out, body, i = bytearray(), lit[1:-1], 0
    while i < len(body):
        if body[i] == "\\":
            if body[i + 1] in '\\"':
                out += body[i + 1].encode()
                i += 2
            else:
                out.append(int(body[i + 1:i + 4], 8))
                i += 4
        else:
            out += body[i].encode()
            i += 1
    return out.decode("utf-8")


def _assert_safe_literal(text: str) -> None:
    lit = osl_string_literal(text)
    assert all(0x20 <= ord(c) < 0x7F for c in lit), lit
    assert "??" not in lit
    assert re.fullmatch(r'"(?:[^"\\]|\\["\\]|\\[0-7]{3})*"', lit), lit
    decoded = _decode_osl_literal(lit)
    assert "\r" not in decoded and "\n" not in decoded and "\0" not in decoded
    # printable text survives, ? included
    for ch in text:
        if ch.isprintable() and ch not in "\u2028\u2029" and not (0xD800 <= ord(ch) < 0xE000):
            assert ch in decoded, (text, decoded)


@pytest.mark.parametrize("text", HOSTILE_NAMES)
def test_osl_string_literal_cannot_be_left(text):
    _assert_safe_literal(text)


@FUZZ
@given(st.text())
def test_osl_string_literal_fuzz(text):
    _assert_safe_literal(text)


@FUZZ
@given(st.text())
def test_osl_identifier_and_comment_fuzz(text):
    ident = osl_identifier(text)
    assert re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", ident) and not ident.startswith("__")
    comment = osl_comment(text)
    assert all(0x20 <= ord(c) < 0x7F for c in comment) and "??" not in comment
    assert not comment.endswith("\\")


def _directives(osl_text: str) -> list[str]:
    return [d.strip() for d in re.findall(r"^[ \t]*#.*$", osl_text, re.M)]


def _compile_hostile_export(tmp_path, name: str, description: str):
    from app.export import blender as B

    osl = tmp_path / "look.osl"
    X.export_osl(Params({}), osl, name=name, description=description)
    text = osl.read_text(encoding="utf-8")
    assert "\r" not in text and "??" not in text.replace("\\077", "")
    assert _directives(text) == _directives(X.osl_source(Params({}), "plain")), "user text made a directive"
    with warnings.catch_warnings():
        warnings.simplefilter("error")              # an oslc warning (a trigraph...) fails the test
        B.compile_osl(osl, tmp_path / "look.oso")
    return B.query_osl(tmp_path / "look.oso")


@pytest.mark.skipif(not HAVE_BPY, reason="bpy is not installed")
@pytest.mark.parametrize("name", HOSTILE_NAMES)
def test_hostile_names_export_to_osl_that_compiles(tmp_path, name):
    q = _compile_hostile_export(tmp_path, name, description=name)
    assert q["name"] == X.shader_name(name or "look")   # export_osl names an unnamed look by its file
    assert re.fullmatch(r"vfiber(_[A-Za-z0-9_]+)?", q["name"])


@pytest.mark.skipif(not HAVE_BPY, reason="bpy is not installed")
def test_osl_injection_through_a_preset_file_name_is_closed(tmp_path):
    """The finding end to end: a preset whose *file name* carries the injection exports, compiles, and its
    shader still calls transparent() (the #define did not take)."""
    from app.export import blender as B

    preset = tmp_path / f"{INJECTION.replace('/', '_')}.toml"
    preset.write_text('version = 2\ndescription = "d\\\\\\r\\"#define transparent emission"\n')
    out = tmp_path / "inj.osl"
    assert X.main([str(preset), "-o", str(out)]) == 0
    B.compile_osl(out, tmp_path / "inj.oso")
    text = out.read_text()
    assert "transparent()" in text and _directives(text) == _directives(X.osl_source(Params({}), "plain"))
    oso = (tmp_path / "inj.oso").read_text(errors="replace")
    assert "transparent" in oso


@pytest.mark.skipif(not HAVE_BPY, reason="bpy is not installed")
@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(name=st.text(max_size=40), description=st.text(max_size=200))
def test_fuzzed_names_and_descriptions_compile(tmp_path, name, description):
    _compile_hostile_export(tmp_path, name, description)
