"""Shader sources: ``#include`` expansion with a line table, ``#define`` variants, and a program cache.

Include paths are relative to the glsl root, never to the including file, so a library file has one
name everywhere (``#include "geometry/container.glsl"``) and include-once is a set of those names.
A file is expanded at its first include; later includes of it are dropped. An include inside an
``#if``/``#ifdef``/``#ifndef`` block (other than the file's own include guard) may be compiled out, so it
does not count as the first: the file is expanded again at its next include and its include guard keeps
the preprocessor from seeing it twice (a file included under ``#if`` must have one; every library file
has one: tests/gl/test_glsl_includes.py). Directives inside block comments are still seen: keep
``#include`` out of comments.

Mesa reports ``0:LINE(COL): error: ...`` and drops source-string ids, so ``#line`` cannot say which file
a line came from; instead ``expand`` returns a table from expanded line to (file, line) that
``ShaderCompileError`` uses to point at ``glsl/fibers/traverse.glsl:87:12``.
"""

from __future__ import annotations

import hashlib
import importlib
import math
import posixpath
import re
import shutil
import subprocess
import tempfile
import weakref
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import VfiberError

if TYPE_CHECKING:
    import moderngl

SourceLine = tuple[str, int]   # (file relative to the glsl root, 1-based line); defines: ("<defines>", n)
LineTable = list[SourceLine]   # LineTable[i] is where expanded line i + 1 came from
Defines = Mapping[str, "int | float | bool | str | None"]

DEFINES_FILE = "<defines>"
STAGE_SUFFIXES = {".vert": "vert", ".frag": "frag", ".geom": "geom", ".comp": "comp",
                  ".tesc": "tesc", ".tese": "tese"}

_INCLUDE = re.compile(r'^\s*#\s*include\s+"(?P<path>[^"]+)"\s*(//.*)?$')
_INCLUDE_LOOSE = re.compile(r"^\s*#\s*include\b")
_VERSION = re.compile(r"^\s*#\s*version\b")
_IF = re.compile(r"^\s*#\s*(if|ifdef|ifndef)\b")
_ENDIF = re.compile(r"^\s*#\s*endif\b")
_IFNDEF = re.compile(r"^\s*#\s*ifndef\s+(?P<name>[A-Za-z_]\w*)\s*(//.*)?$")
_DEFINE_BARE = re.compile(r"^\s*#\s*define\s+(?P<name>[A-Za-z_]\w*)\s*(//.*)?$")
_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")

# Driver log locations: Mesa "0:12(5): error: ...", NVIDIA "0(12) : error C0000: ...",
# AMD and glslang "ERROR: 0:12: ...". The source-string id is ignored (Mesa always says 0).
_LOCATIONS = (
    re.compile(r"^(?P<src>\d+):(?P<line>\d+)\((?P<col>\d+)\): (?P<msg>.*)$"),
    re.compile(r"^(?P<src>\d+)\((?P<line>\d+)\) ?: (?P<msg>.*)$"),
    re.compile(r"^(?P<sev>ERROR|WARNING): (?P<src>[^:\s]+):(?P<line>\d+): (?P<msg>.*)$"),
)


class ShaderError(VfiberError, RuntimeError):
    """Base for shader source problems; the message names files as glsl/path:line."""


class ShaderIncludeError(ShaderError):
    """A missing file, an include cycle or a malformed directive."""


class ShaderCompileError(ShaderError):
    """The driver (or glslangValidator) rejected the expanded source; locations point into glsl/."""

    def __init__(self, message: str, diagnostics: list[str], log: str) -> None:
        super().__init__(message)
        self.diagnostics = diagnostics  # one "glsl/file.glsl:LINE:COL: text" per driver message
        self.log = log                  # the driver's own words, unmapped


def glsl_root() -> Path:
    """The shader library: the packaged ``app.glsl`` (pyproject maps it to ``glsl/``), else the checkout's."""
    try:
        from importlib.resources import files

        resource = files("app.glsl")
        if isinstance(resource, Path) and resource.is_dir():
            return resource
        # glsl/ has no __init__.py, so an install may make it a namespace package without a plain path.
        paths = list(getattr(importlib.import_module("app.glsl"), "__path__", []))
        if paths and Path(paths[0]).is_dir():
            return Path(paths[0])
    except (ImportError, TypeError, ValueError):
        pass
    return Path(__file__).resolve().parents[2] / "glsl"


def _label(root: Path, rel: str) -> str:
    """How a person sees a file: the root folder's name then the relative path, e.g. glsl/common/hash.glsl."""
    return rel if rel == DEFINES_FILE else f"{root.name}/{rel}"


def define_lines(defines: Defines | None) -> list[str]:
    """``#define`` lines in name order, so equal dicts give equal sources (and equal cache hashes)."""
    lines = []
    for name in sorted(defines or {}):
        value = (defines or {})[name]
        if not _IDENTIFIER.fullmatch(name):
            raise ValueError(f"#define name {name!r} is not a GLSL identifier")
        if value is None:
            lines.append(f"#define {name}")
            continue
        if isinstance(value, bool):
            text = "1" if value else "0"
        elif isinstance(value, int):
            text = str(value)
        elif isinstance(value, float):
            if not math.isfinite(value):
                raise ValueError(f"#define {name}: {value!r} has no GLSL literal")
            text = repr(value)
        elif isinstance(value, str) and "\n" not in value:
            text = value
        else:
            raise ValueError(f"#define {name}: {value!r} must be None, bool, int, float or a one-line str")
        lines.append(f"#define {name} {text}")
    return lines


def include_guard(lines: list[str]) -> tuple[str, int] | None:
    """(NAME, 1-based line of its ``#ifndef``) when the file's first conditional is an include guard:
    ``#ifndef NAME`` then ``#define NAME`` (no value; blank and comment lines between are allowed) whose
    ``#endif`` is the file's last line of code. Else None."""
    def code(line: str) -> bool:
        text = line.strip()
        return bool(text) and not text.startswith("//")

    first = next((i for i, line in enumerate(lines) if _IF.match(line)), None)
    if first is None:
        return None
    opened = _IFNDEF.match(lines[first])
    after = next((line for line in lines[first + 1:] if code(line)), "")
    defined = _DEFINE_BARE.match(after)
    if not opened or not defined or defined["name"] != opened["name"]:
        return None
    # the #ifndef's own #endif must be the file's last line of code
    depth = 0
    for i in range(first, len(lines)):
        if _IF.match(lines[i]):
            depth += 1
        elif _ENDIF.match(lines[i]):
            depth -= 1
            if depth == 0:
                return None if any(code(line) for line in lines[i + 1:]) else (opened["name"], first + 1)
    return None


@dataclass
class _Expander:
    root: Path
    lines: list[str] = field(default_factory=list)
    table: LineTable = field(default_factory=list)
    done: set[str] = field(default_factory=set)
    mtimes: dict[Path, int | None] = field(default_factory=dict)  # every file looked at, for hot reload

    def include(self, rel: str, stack: list[SourceLine], site: SourceLine | None,
                conditional: bool = False) -> None:
        where = f"{_label(self.root, site[0])}:{site[1]}: " if site else ""
        norm = posixpath.normpath(rel)
        if norm.startswith(("/", "../")) or norm == "..":
            raise ShaderIncludeError(f'{where}cannot include "{rel}": paths are relative to '
                                     f"{self.root.name}/ and stay inside it")
        chain = [name for name, _ in stack]
        if norm in chain:
            hops = [f"{_label(self.root, name)}:{line}" for name, line in stack[chain.index(norm):]]
            raise ShaderIncludeError("include cycle: " + " -> ".join(hops + [_label(self.root, norm)]))
        if norm in self.done:
            return
        path = self.root / norm
        try:
            self.mtimes[path] = path.stat().st_mtime_ns  # before reading: an edit after this is seen later
            text = path.read_text(encoding="utf-8")
        except OSError:
            self.mtimes[path] = None
            target = _label(self.root, norm)
            raise ShaderIncludeError(f'{where}cannot include "{rel}": {target} does not exist'
                                     if site else f"{target} does not exist (glsl root {self.root})") from None
        lines = text.splitlines()
        guard = include_guard(lines)
        if conditional and guard is None:
            raise ShaderIncludeError(f"{where}{_label(self.root, norm)} is included inside #if: give it an include "
                                     "guard (#ifndef NAME / #define NAME ... #endif) so a later include of "
                                     "it cannot define it twice")
        if not conditional:
            self.done.add(norm)
        blocks: list[bool] = []     # per open #if: whether it may be compiled out (the guard may not)
        for number, line in enumerate(lines, start=1):
            match = _INCLUDE.match(line)
            if match:
                self.include(match["path"], stack + [(norm, number)], (norm, number),
                             conditional or any(blocks))
                continue
            if _IF.match(line):
                blocks.append(guard is None or number != guard[1])
            elif _ENDIF.match(line) and blocks:
                blocks.pop()
            if _INCLUDE_LOOSE.match(line):
                raise ShaderIncludeError(f'{_label(self.root, norm)}:{number}: write #include "path.glsl"')
            self.lines.append(line)
            self.table.append((norm, number))


def _expand(expander: _Expander, path: str, defines: Defines | None) -> _Expander:
    expander.include(path, [], None)
    injected = define_lines(defines)
    # Defines go right after #version (which must stay first); without one, at the very top.
    at = next((i + 1 for i, line in enumerate(expander.lines) if _VERSION.match(line)), 0)
    expander.lines[at:at] = injected
    expander.table[at:at] = [(DEFINES_FILE, n) for n in range(1, len(injected) + 1)]
    return expander


def expand(path: str, defines: Defines | None = None, root: Path | str | None = None) -> tuple[str, LineTable]:
    """The source of ``path`` (relative to ``root``, default ``glsl_root()``) with includes and defines in."""
    expander = _expand(_Expander(Path(root) if root is not None else glsl_root()), path, defines)
    return "\n".join(expander.lines) + "\n", expander.table


def map_log(log: str, table: LineTable, root: Path) -> list[str]:
    """Driver messages with each location rewritten to ``glsl/file.glsl:LINE[:COL]: text``."""
    out = []
    for raw in log.splitlines():
        line = raw.strip()
        if not line:
            continue
        for pattern in _LOCATIONS:
            match = pattern.match(line)
            if match:
                number = int(match["line"])
                if 1 <= number <= len(table):
                    rel, src_line = table[number - 1]
                    place = f"{_label(root, rel)}:{src_line}"
                else:
                    place = f"<expanded>:{number}"
                col = match.groupdict().get("col")
                severity = match.groupdict().get("sev")
                text = f"{severity.lower()}: {match['msg']}" if severity else match["msg"]
                out.append(f"{place}:{col}: {text}" if col else f"{place}: {text}")
                break
        else:
            out.append(line)
    return out


_STAGE_HEADERS = {"vertex_shader": "vertex", "fragment_shader": "fragment", "Program": "link"}


def _compile_error(log: str, stages: dict[str, tuple[str, LineTable]], root: Path,
                   defines: Defines | None) -> ShaderCompileError:
    """Split moderngl's "GLSL Compiler failed\\n\\nfragment_shader\\n=====\\n<log>" by stage and map each part."""
    diagnostics: list[str] = []
    current: LineTable = []
    lines = log.splitlines()
    for i, line in enumerate(lines):
        header = line.strip()
        underlined = i + 1 < len(lines) and set(lines[i + 1].strip()) == {"="}
        if underlined and header in _STAGE_HEADERS:
            current = stages.get(_STAGE_HEADERS[header], ("", []))[1]
            continue
        if set(header) == {"="} or header in ("GLSL Compiler failed", "GLSL Linker failed"):
            continue
        diagnostics.extend(map_log(line, current, root))
    files = " + ".join(_label(root, path) for path, _ in stages.values())
    variant = ", ".join(f"{k}={v}" for k, v in sorted((defines or {}).items()))
    head = f"{files} failed to {'link' if 'Linker' in log else 'compile'}" + (f" with {variant}" if variant else "")
    return ShaderCompileError("\n".join([head + ":"] + ["  " + d for d in diagnostics]), diagnostics, log)


@dataclass
class _PerContext:
    by_key: dict[tuple[str, str, tuple[str, ...]], moderngl.Program] = field(default_factory=dict)
    by_hash: dict[str, moderngl.Program] = field(default_factory=dict)


class ProgramCache:
    """Compiled programs per context, keyed by a hash of the expanded sources and defines.

    ``get`` first looks up (vertex, fragment, defines) so a frame costs no file reads; ``sources_changed``
    stats the files behind every program (and behind a failed attempt), and ``invalidate`` forgets them all
    for a hot reload. Forgotten programs are not released: the viewer keeps drawing with the old one until
    the new one compiles, and moderngl frees them with the context.
    """

    def __init__(self, root: Path | str | None = None) -> None:
        self.root = Path(root) if root is not None else glsl_root()
        self._contexts: weakref.WeakKeyDictionary[moderngl.Context, _PerContext] = weakref.WeakKeyDictionary()
        self._mtimes: dict[Path, int | None] = {}

    def expand(self, path: str, defines: Defines | None = None) -> tuple[str, LineTable]:
        return expand(path, defines, self.root)

    def get(self, ctx: moderngl.Context, vertex: str, fragment: str,
            defines: Defines | None = None) -> moderngl.Program:
        import moderngl

        per = self._contexts.setdefault(ctx, _PerContext())
        key = (vertex, fragment, tuple(define_lines(defines)))
        if key in per.by_key:
            return per.by_key[key]
        expanded = {}
        for stage, path in (("vertex", vertex), ("fragment", fragment)):
            expander = _Expander(self.root)
            try:
                _expand(expander, path, defines)
            finally:
                self._mtimes.update(expander.mtimes)  # watch even a failed attempt: fixing it reloads
            expanded[stage] = (path, expander.lines, expander.table)
        vtext = "\n".join(expanded["vertex"][1]) + "\n"
        ftext = "\n".join(expanded["fragment"][1]) + "\n"
        digest = hashlib.sha256("\0".join((vtext, ftext) + key[2]).encode()).hexdigest()
        program = per.by_hash.get(digest)
        if program is None:
            try:
                program = ctx.program(vertex_shader=vtext, fragment_shader=ftext)
            except moderngl.Error as exc:
                stages = {stage: (path, table) for stage, (path, _, table) in expanded.items()}
                raise _compile_error(str(exc), stages, self.root, defines) from None
            per.by_hash[digest] = program
        per.by_key[key] = program
        return program

    def invalidate(self) -> None:
        self._contexts.clear()
        self._mtimes.clear()

    def sources_changed(self) -> bool:
        for path, seen in self._mtimes.items():
            try:
                now: int | None = path.stat().st_mtime_ns
            except OSError:
                now = None
            if now != seen:
                return True
        return False


def glslang_path() -> str | None:
    return shutil.which("glslangValidator")


def validate_with_glslang(path: str, defines: Defines | None = None, root: Path | str | None = None) -> None:
    """Lint a stage file (after include expansion) with glslangValidator; raise ShaderCompileError on errors.

    A second compiler catches what llvmpipe forgives (NVIDIA and AMD are stricter than Mesa).
    """
    exe = glslang_path()
    if exe is None:
        raise ShaderError("glslangValidator not found: apt-get install glslang-tools")
    root_path = Path(root) if root is not None else glsl_root()
    stage = STAGE_SUFFIXES.get(Path(path).suffix)
    if stage is None:
        raise ShaderError(f"{_label(root_path, path)}: not a stage file ({', '.join(STAGE_SUFFIXES)})")
    text, table = expand(path, defines, root_path)
    with tempfile.TemporaryDirectory() as tmp:
        source = Path(tmp) / f"shader.{stage}"
        source.write_text(text, encoding="utf-8")
        result = subprocess.run([exe, "-S", stage, str(source)], capture_output=True, text=True, timeout=60)
    if result.returncode != 0:
        log = (result.stdout + result.stderr).replace(str(source), "0")
        diagnostics = [d for d in map_log(log, table, root_path)
                       if d != "0" and "compilation terminated" not in d and "No code generated" not in d]
        message = f"{_label(root_path, path)} fails glslangValidator:\n" + "\n".join("  " + d for d in diagnostics)
        raise ShaderCompileError(message, diagnostics, log)
