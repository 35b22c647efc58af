"""Self-contained shader sources: every glsl/ and osl/ library file has an include guard and includes what
it uses, so it compiles alone and no file relies on the include order of another.

GLSL: each library file, expanded with its own includes only (app/gl/shaders.py), is wrapped in a trivial
fragment stage and compiled by glslangValidator. OSL has no compiler here (Cycles compiles the export inside
Blender), so each osl/ file is checked by symbol: every vf_ function, Vf struct and VF_ macro it uses is
defined in the file or in the files it includes, directly or through them.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

from app.fibers import osl_header
from app.gl import shaders
from app.gl.shaders import STAGE_SUFFIXES, ShaderIncludeError, expand, include_guard, map_log
from tests.support.paths import ROOT

GLSL = ROOT / "glsl"
OSL = ROOT / "osl"
OSL_STAGE = "stages/container.osl"   # the shader body: read as text by app/export/osl_source.py, never included

GLSL_LIBRARY = sorted(str(p.relative_to(GLSL)) for p in GLSL.rglob("*.glsl"))
OSL_LIBRARY = sorted(str(p.relative_to(OSL)) for p in OSL.rglob("*.osl") if str(p.relative_to(OSL)) != OSL_STAGE)
_INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)


def guard_name(rel: str) -> str:
    """The guard a file's path gives it: glsl/fibers/hit.glsl -> FIBERS_HIT_GLSL."""
    return re.sub(r"[^A-Za-z0-9]", "_", rel).upper()


def _code_before_guard(lines: list[str], guard_line: int) -> list[str]:
    """Lines above the guard other than comments, blanks and #include: none may stand outside it."""
    return [line for line in lines[:guard_line - 1]
            if line.strip() and not line.lstrip().startswith("//") and not _INCLUDE.match(line)]


def test_the_libraries_are_found():
    assert "fibers/traverse.glsl" in GLSL_LIBRARY and "fibers/traverse.osl" in OSL_LIBRARY
    assert not [rel for rel in GLSL_LIBRARY if Path(rel).suffix in STAGE_SUFFIXES]


@pytest.mark.parametrize("root,rel", [(GLSL, r) for r in GLSL_LIBRARY] + [(OSL, r) for r in OSL_LIBRARY],
                         ids=lambda x: str(x) if isinstance(x, str) else x.name)
def test_every_library_file_has_its_include_guard(root: Path, rel: str):
    lines = (root / rel).read_text(encoding="utf-8").splitlines()
    guard = include_guard(lines)
    assert guard is not None, (f"{root.name}/{rel} has no include guard: put #ifndef {guard_name(rel)} / "
                               f"#define {guard_name(rel)} below its header and includes, #endif last")
    name, line = guard
    assert name == guard_name(rel), f"{root.name}/{rel}:{line}: guard {name}, expected {guard_name(rel)}"
    assert not _code_before_guard(lines, line), f"{root.name}/{rel}: code above the include guard"


# ---------------------------------------------------------------------------------------------- GLSL alone

needs_glslang = pytest.mark.skipif(shaders.glslang_path() is None,
                                   reason="glslangValidator not installed (apt-get install glslang-tools)")


def compile_alone(rel: str, defines: dict | None = None, root: Path = GLSL) -> list[str]:
    """glslangValidator's diagnostics for ``rel`` with its includes, inside an empty fragment stage;
    locations mapped back to glsl/file:line. Empty when it compiles."""
    text, table = expand(rel, defines, root)
    source = "#version 450 core\n" + text + "void main() {}\n"
    table = [("<wrapper>", 1)] + table + [("<wrapper>", 2)]
    result = subprocess.run([shaders.glslang_path(), "--stdin", "-S", "frag"], input=source,
                            capture_output=True, text=True, timeout=60)
    if result.returncode == 0:
        return []
    log = (result.stdout + result.stderr).replace("stdin", "0")
    return [d for d in map_log(log, table, root) if "compilation terminated" not in d
            and "No code generated" not in d and d != "0"] or [log]


@needs_glslang
@pytest.mark.parametrize("rel", GLSL_LIBRARY)
def test_every_glsl_file_compiles_alone(rel: str):
    errors = compile_alone(rel)
    assert not errors, f"glsl/{rel} does not compile on its own with its includes:\n" + "\n".join(errors)


@needs_glslang
@pytest.mark.parametrize("defines", [{"SHAPED": 1}, {"SHAPED": 1, "TRAVERSAL": 2}, {"TRAVERSAL": 0},
                                     {"COST_PASS": 1}], ids=str)
def test_the_traversal_variants_compile_alone(defines):
    errors = compile_alone("fibers/traverse.glsl", defines)
    assert not errors, f"glsl/fibers/traverse.glsl with {defines}:\n" + "\n".join(errors)


@needs_glslang
def test_the_check_fails_for_a_file_that_uses_what_it_does_not_include(tmp_path: Path):
    """The guard against the old curved.glsl: a file that compiled only after its includer's includes."""
    (tmp_path / "lib").mkdir()
    (tmp_path / "lib" / "a.glsl").write_text("#ifndef LIB_A_GLSL\n#define LIB_A_GLSL\n"
                                             "float lib_a() { return 1.0; }\n#endif\n")
    (tmp_path / "lib" / "b.glsl").write_text("#ifndef LIB_B_GLSL\n#define LIB_B_GLSL\n"
                                             "float lib_b() { return lib_a(); }\n#endif\n")
    errors = compile_alone("lib/b.glsl", root=tmp_path)
    assert errors and any("lib/b.glsl:3" in e and "lib_a" in e for e in errors), errors


# ------------------------------------------------------------------------- the resolver and include guards

def _tree(tmp_path: Path, files: dict[str, str]) -> Path:
    for rel, text in files.items():
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text(text)
    return tmp_path


GUARDED_A = "// a\n#ifndef A_GLSL\n#define A_GLSL\nfloat a() { return 1.0; }\n#endif\n"


def test_an_include_under_if_does_not_hide_a_later_include(tmp_path: Path):
    """A file first included inside #if (maybe compiled out) is expanded again at its next include: with
    include-once alone its text would be dropped there, and missing whenever the #if is false."""
    root = _tree(tmp_path, {"a.glsl": GUARDED_A,
                            "s.frag": '#version 450 core\n#if OPTION\n#include "a.glsl"\n#endif\n'
                                      '#include "a.glsl"\nvoid main() {}\n'})
    text, table = expand("s.frag", {"OPTION": 0}, root)
    assert text.count("float a()") == 2
    # the line table still names every line's origin
    lines = text.splitlines()
    for i, line in enumerate(lines):
        if line.startswith("float a()"):
            assert table[i] == ("a.glsl", 4)
    # ... and once included outside any #if, the file is done: no third copy
    root2 = _tree(tmp_path / "t", {"a.glsl": GUARDED_A,
                                   "s.frag": '#include "a.glsl"\n#if OPTION\n#include "a.glsl"\n#endif\n'})
    assert expand("s.frag", None, root2)[0].count("float a()") == 1


@needs_glslang
def test_an_include_under_if_compiles_both_ways(tmp_path: Path):
    root = _tree(tmp_path, {"a.glsl": GUARDED_A,
                            "b.glsl": '#include "a.glsl"\n#ifndef B_GLSL\n#define B_GLSL\n'
                                      "float b() { return a(); }\n#endif\n",
                            "lib.glsl": '#ifndef LIB_GLSL\n#define LIB_GLSL\n#if OPTION\n#include "b.glsl"\n'
                                        '#endif\n#include "a.glsl"\nfloat lib() { return a(); }\n#endif\n'})
    for option in (0, 1):
        assert not compile_alone("lib.glsl", {"OPTION": option}, root)


def test_the_own_guard_is_not_a_condition(tmp_path: Path):
    """Includes inside a file's own guard count as unconditional: the file is expanded once."""
    root = _tree(tmp_path, {"a.glsl": GUARDED_A,
                            "b.glsl": '#ifndef B_GLSL\n#define B_GLSL\n#include "a.glsl"\n#endif\n',
                            "s.frag": '#include "b.glsl"\n#include "a.glsl"\n'})
    assert expand("s.frag", None, root)[0].count("float a()") == 1


def test_an_unguarded_file_under_if_is_refused(tmp_path: Path):
    root = _tree(tmp_path, {"a.glsl": "float a() { return 1.0; }\n",
                            "s.frag": '#version 450 core\n#ifdef X\n#include "a.glsl"\n#endif\n'})
    with pytest.raises(ShaderIncludeError, match=r"s\.frag:3: .*a\.glsl is included inside #if: give it an "
                                                 r"include guard"):
        expand("s.frag", None, root)


@pytest.mark.parametrize("text,guard", [
    (GUARDED_A, ("A_GLSL", 2)),
    ("#ifndef A\n#define A 1\n#endif\nfloat a();\n", None),        # a default value, not a guard
    ("#ifndef A\n#define A\n#endif\nfloat a();\n", None),          # code after the #endif
    ("#ifndef A\n#define B\nfloat a();\n#endif\n", None),          # defines another name
    ("float a();\n", None),
    ('#include "x.glsl"\n\n#ifndef A\n// why\n#define A\n#if X\n#endif\n#endif\n', ("A", 3)),
])
def test_include_guard_recognition(text: str, guard):
    assert include_guard(text.splitlines()) == guard


# ----------------------------------------------------------------------------------------- OSL by symbol

_OSL_DEF = re.compile(r"^(?:void|int|float|point|vector|normal|color|matrix|string|Vf\w+)\s+(vf_\w+)\s*\(", re.M)
_OSL_STRUCT = re.compile(r"^struct\s+(Vf\w+)", re.M)
_OSL_MACRO = re.compile(r"^\s*#\s*define\s+(VF_\w+)", re.M)
_OSL_USE = re.compile(r"\b(vf_\w+|Vf\w+|VF_\w+)\b")


def _osl_code(rel: str, root: Path = OSL) -> str:
    text = (root / rel).read_text(encoding="utf-8")
    code = re.sub(r"//[^\n]*", "", text)
    # attribute names ("vf_p0") are strings, not symbols; an include's path stays for _INCLUDE
    return re.sub(r'(?<!include )"[^"\n]*"', '""', code)


def _osl_defines(code: str) -> set[str]:
    return set(_OSL_DEF.findall(code)) | set(_OSL_STRUCT.findall(code)) | set(_OSL_MACRO.findall(code))


def _osl_reach(rel: str, root: Path = OSL, seen: set[str] | None = None) -> set[str]:
    """Every name defined in ``rel`` and in what it includes, directly or through them."""
    seen = set() if seen is None else seen
    if rel in seen:
        return set()
    seen.add(rel)
    code = _osl_code(rel, root)
    names = _osl_defines(code)
    for inc in _INCLUDE.findall(code):
        names |= _osl_reach(inc, root, seen)
    return names


# the fiber model's numbers (app.fibers.osl_header) sit above every exported library, so no file includes them
_MODEL_DEFINES = _osl_defines(osl_header())


def osl_missing(rel: str, root: Path = OSL) -> list[str]:
    """The vf_ / Vf / VF_ names ``rel`` uses that neither it nor its includes define."""
    code = _osl_code(rel, root)
    for inc in _INCLUDE.findall(code):
        assert (root / inc).is_file(), f"{root.name}/{rel} includes {inc}, which does not exist"
    used = set(_OSL_USE.findall(code)) - {guard_name(rel)} - _MODEL_DEFINES
    return sorted(used - _osl_reach(rel, root))


@pytest.mark.parametrize("rel", OSL_LIBRARY)
def test_every_osl_file_includes_what_it_uses(rel: str):
    missing = osl_missing(rel)
    assert not missing, f"osl/{rel} uses {missing} without including the file that defines them"


def test_the_osl_check_sees_a_missing_include(tmp_path: Path):
    _tree(tmp_path, {"a.osl": "#define VF_A 1\nstruct VfA { float x; };\nfloat vf_a(VfA v) { return v.x; }\n",
                     "b.osl": '#include "a.osl"\nfloat vf_b(VfA v) { return vf_a(v) + VF_A; }\n',
                     "c.osl": 'float vf_c(VfA v) { return vf_a(v); }  // "vf_d" in a string is no use\n',
                     "d.osl": '#include "b.osl"\nfloat vf_d(VfA v) { string s = "vf_nothing"; return vf_b(v); }\n'})
    assert osl_missing("b.osl", tmp_path) == []
    assert osl_missing("c.osl", tmp_path) == ["VfA", "vf_a"]
    assert osl_missing("d.osl", tmp_path) == []        # through b.osl; the string names nothing
