"""Preset files: a look (every parameter of ``app.params.SPEC``) saved as TOML.

A preset is data only: it is parsed with ``tomllib`` and validated against SPEC, nothing in it is ever
executed or imported.  Format (version 2)::

    version = 2
    name = "Blonde carpet"
    description = "You should see a carpet of light, slightly wavy hairs."

    [fibers]
    rings = 10
    phi_step = 1.0

    [look]
    color = [0.55, 0.36, 0.2]

Any parameter left out takes its default.  Older versions migrate forward one step at a time through
``MIGRATIONS``, so a file written by any earlier vfiber still opens.

Every problem is reported as a ``PresetError`` naming the file, the line (found by scanning the TOML text,
because ``tomllib`` does not keep positions), the key, the value and what is allowed.

``python -m app.presets --docs`` regenerates ``docs/parameters.md`` from SPEC (``--check`` only compares).
"""

from __future__ import annotations

import argparse
import difflib
import importlib.resources
import os
import re
import stat
import sys
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from collections.abc import Callable, Iterable

import tomli_w

from app.atomic import atomic_write_text
from app.errors import UsageError
from app.params import (BY_KEY, GROUPS, SPEC, Param, ParamError, Params, max_fiber_radius, short_repr,
                        suggest, with_assignments)
from app.scene.grooms import GROOM_SUFFIXES

PRESET_VERSION = 2
TOP_LEVEL = ("version", "name", "description")  # scalars allowed above the tables
DOCS_PATH = Path(__file__).resolve().parents[1] / "docs" / "parameters.md"
_SHORT = 60  # longest value repr quoted in a message; a 10 000-element array would bury the point
MAX_PRESET_BYTES = 1024 * 1024  # a full preset is ~5 KB; a larger file is the wrong file, not a look
MAX_PROBLEMS = 20  # problems described per preset; the rest are counted


class PresetError(ParamError):
    """A preset file is unusable. ``str(e)`` is ``file:line: message``; ``key``, ``source`` (the file) and
    ``line`` are also attributes.  When a file has several problems the first one (by line) is the error
    and the others follow in the message, so an artist can fix them all in one go."""


@dataclass(frozen=True)
class Preset:
    name: str                # display name; the file stem when the file has no ``name``
    description: str         # one line: what you should see when it renders
    params: Params
    path: Path | None = None


# --------------------------------------------------------------------------------------------------
# migrations: MIGRATIONS[n] turns a parsed version-n document into a version-(n+1) one

# Version 1 (the first format) had one flat [params] table with the thesis's names.  One old key can feed
# several new ones: a single ``jitter`` drove both the radial and the angular offset.
V1_RENAMES: dict[str, tuple[str, ...]] = {
    "internal_cylinders": ("fibers.rings",),
    "phi_step": ("fibers.phi_step",),
    "phi_step_increment": ("fibers.phi_increment",),
    "jitter": ("fibers.radial_jitter", "fibers.angular_jitter"),
    "fiber_radius": ("fibers.fiber_radius",),
}


def migrate_1_to_2(doc: dict[str, Any]) -> dict[str, Any]:
    """``[params] internal_cylinders = 8`` -> ``[fibers] rings = 8`` etc.  Values are not checked here:
    the normal version-2 validation does that, with line numbers pointing at the old keys."""
    unknown = [k for k in doc if k not in ("version", "name", "description", "params")]
    if unknown:
        raise ParamError(f"unknown top-level key {unknown[0]!r} in a version-1 preset: version 1 has "
                         "version, name, description and a [params] table", key=unknown[0])
    old = doc.get("params", {})
    if not isinstance(old, dict):
        raise ParamError(f"params = {_short(old)} should be a table: write [params] and put "
                         "name = value lines under it", key="params")
    out: dict[str, Any] = {k: v for k, v in doc.items() if k != "params"}
    for name, value in old.items():
        if name not in V1_RENAMES:
            near = difflib.get_close_matches(name, V1_RENAMES, n=1)
            hint = f" (did you mean {near[0]!r}?)" if near else ""
            raise ParamError(f"unknown version-1 key params.{name} = {_short(value)}{hint}; version 1 "
                             f"knows: {', '.join(V1_RENAMES)}", key=f"params.{name}")
        for new_key in V1_RENAMES[name]:
            group, new_name = new_key.split(".", 1)
            out.setdefault(group, {})[new_name] = value
    out["version"] = 2
    return out


MIGRATIONS: dict[int, Callable[[dict[str, Any]], dict[str, Any]]] = {1: migrate_1_to_2}

# Where a version-2 key came from in an older file, so errors after migration still point at a line.
_OLD_LOCATION: dict[int, dict[str, str]] = {
    1: {new: f"params.{old}" for old, news in V1_RENAMES.items() for new in news},
}


# --------------------------------------------------------------------------------------------------
# finding lines: tomllib keeps no positions, so scan the text for ``key =`` inside its ``[table]``

_HEADER = re.compile(r"""^\s*\[\[?\s*([^\[\]#]+?)\s*\]\]?\s*(?:#.*)?$""")  # [table] or [[array]]
_KEY_PART = r"""(?:[A-Za-z0-9_-]+|"[^"]*"|'[^']*')"""
_KEYLINE = re.compile(rf"""^\s*({_KEY_PART}(?:\s*\.\s*{_KEY_PART})*)\s*=""")
_PART = re.compile(r"""[A-Za-z0-9_-]+|"[^"]*"|'[^']*'""")


def _parts(dotted: str) -> tuple[str, ...]:
    return tuple(p.strip("\"'") for p in _PART.findall(dotted))


class _Locator:
    """Line numbers (1-based) of tables and keys.  Best effort: a key inside an inline table or split
    oddly falls back to the line of its table, and anything not found gives None."""

    def __init__(self, text: str):
        self.lines: dict[tuple[str, ...], int] = {}
        table: tuple[str, ...] = ()
        in_string: str | None = None  # inside a multi-line string nothing is a key
        for number, line in enumerate(text.split("\n"), 1):  # TOML breaks lines only at \n
            if in_string:
                if line.count(in_string) % 2:
                    in_string = None
                continue
            header = _HEADER.match(line)
            if header:
                table = _parts(header.group(1))
                self.lines.setdefault(table, number)
                continue
            keyline = _KEYLINE.match(line)
            if keyline:
                path = table + _parts(keyline.group(1))
                self.lines.setdefault(path, number)
                rest = line[keyline.end():]
                if rest.lstrip().startswith("{"):  # inline table: record its keys on this line too
                    for inner in re.finditer(r"([A-Za-z0-9_-]+)\s*=", rest):
                        self.lines.setdefault(path + (inner.group(1),), number)
            for quote in ('"""', "'''"):
                if line.count(quote) % 2:
                    in_string = quote
                    break

    def line(self, key: str | None) -> int | None:
        if not key:
            return None
        path = tuple(key.split("."))
        while path:  # the key itself, else the table holding it
            if path in self.lines:
                return self.lines[path]
            path = path[:-1]
        return None


# --------------------------------------------------------------------------------------------------
# loading

def load_preset(path: str | os.PathLike[str]) -> Preset:
    """Read and validate a preset file; raise PresetError (never anything else) if it is unusable."""
    path = Path(path)
    data = _read_preset_bytes(path)
    preset = loads_preset(data, source=str(path))
    return Preset(preset.name or path.stem, preset.description, preset.params, path)


def _read_preset_bytes(path: Path) -> bytes:
    """The file's bytes, refusing what is not a regular file (a FIFO would block, a device never end) and
    reading at most one byte past MAX_PRESET_BYTES."""
    try:
        info = path.stat()
        if not stat.S_ISREG(info.st_mode):
            raise PresetError(f"cannot read the preset: it is {_file_kind(info.st_mode)}, not a regular file",
                              source=str(path))
        if info.st_size > MAX_PRESET_BYTES:
            raise PresetError(_too_big(info.st_size), source=str(path))
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
        with os.fdopen(fd, "rb") as f:
            data = f.read(MAX_PRESET_BYTES + 1)  # at most 1 MiB: cheap to preallocate
    except OSError as e:
        raise PresetError(f"cannot read the preset: {e.strerror or e}", source=str(path)) from None
    if len(data) > MAX_PRESET_BYTES:
        raise PresetError(_too_big(len(data)), source=str(path))
    return data


def _too_big(size: int) -> str:
    return (f"{size} bytes is larger than the {MAX_PRESET_BYTES}-byte limit for presets (a full preset is "
            "about 5 KB): is this the right file?")


def _file_kind(mode: int) -> str:
    for test, what in ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
                       (stat.S_ISSOCK, "a socket"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device")):
        if test(mode):
            return what
    return "not a regular file"


def loads_preset(data: str | bytes, source: str = "<preset>") -> Preset:
    """Parse preset text (or bytes); ``source`` names it in messages."""
    if len(data) > MAX_PRESET_BYTES:
        raise PresetError(_too_big(len(data)), source=source)
    if isinstance(data, bytes):
        try:
            text = data.decode("utf-8-sig")  # tolerate the BOM some Windows editors write
        except UnicodeDecodeError as e:
            line = data[:e.start].count(b"\n") + 1
            raise PresetError(f"not UTF-8 text (byte {e.start} is {data[e.start:e.start + 1]!r}): a preset "
                              "is a TOML text file", source=source, line=line) from None
    else:
        text = data
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise _syntax_error(e, text, source) from None
    except RecursionError:
        deep = re.search(r"[\[{]{50,}|(?:[A-Za-z0-9_-]+\.){50,}", text)
        line = text.count("\n", 0, deep.start()) + 1 if deep else None
        key = _key_on_line(text, line)
        raise PresetError(f"TOML nested too deeply{key}: a preset has tables one level deep ([group] then "
                          "name = value)", source=source, line=line) from None
    except ValueError:  # tomllib lets int()'s digit limit escape: "Exceeds the limit (4300 digits)"
        long = re.search(r"[0-9_]{4000,}", text)
        line = text.count("\n", 0, long.start()) + 1 if long else None
        raise PresetError(f"TOML syntax error: a number thousands of digits long{_key_on_line(text, line)}",
                          source=source, line=line) from None

    where = _Locator(text)
    version = _check_version(doc, where, source)
    try:
        for step in range(version, PRESET_VERSION):
            doc = MIGRATIONS[step](doc)
    except ParamError as e:
        raise PresetError(e.bare, key=e.key, source=source, line=where.line(e.key)) from None

    old_names = _OLD_LOCATION.get(version, {})

    def locate(key: str | None) -> int | None:
        return where.line(old_names.get(key or "", key))

    def note(key: str | None) -> str:
        old = old_names.get(key or "")
        return f" (from {old} in this version-{version} preset)" if old else ""

    values, problems = _collect(doc)
    if problems:
        errors, told = [], set()
        for key, msg in problems:
            old = old_names.get(key or "")
            if old and old in told:  # one old key feeding two new ones: report the old one once
                continue
            told.add(old)
            errors.append(PresetError(msg + note(key), key=key, source=source, line=locate(key)))
        raise _combine(errors)
    try:
        params = Params(values)
    except ParamError as e:  # relations between parameters, e.g. fiber_radius too thick for rings
        raise PresetError(e.bare + note(e.key), key=e.key, source=source, line=locate(e.key)) from None
    return Preset(doc.get("name", ""), doc.get("description", ""), params)


def _key_on_line(text: str, line: int | None) -> str:
    """`` (key fibers.rings)`` for the ``name =`` that starts ``line``, else nothing."""
    if not line:
        return ""
    found = _KEYLINE.match(text.split("\n", line)[line - 1][:200])
    return f" (key {short_repr(found.group(1).strip(), 40)[1:-1]})" if found else ""


def _syntax_error(e: tomllib.TOMLDecodeError, text: str, source: str) -> PresetError:
    # Python < 3.14 puts the position only into the message: "Invalid value (at line 3, column 9)".
    msg = str(e)
    m = re.search(r"\(at line (\d+), column (\d+)\)", msg)
    line = int(m.group(1)) if m else None
    if "(at end of document)" in msg:
        line = text.count("\n") + 1
    lines = text.split("\n")
    # Quote the line only when it is plain text: a file that is not a preset at all (say /proc/self/environ
    # given by mistake) must not have its contents printed into a terminal or a log.
    offending = lines[line - 1].strip() if line and line <= len(lines) else ""
    shown = f": {_short(offending)}" if offending and offending.isprintable() and line <= 10_000 else ""
    return PresetError(f"TOML syntax error: {msg}{shown} - check quotes, brackets and the 'name = value' "
                       "form", source=source, line=line)


def _check_version(doc: dict[str, Any], where: _Locator, source: str) -> int:
    if "version" not in doc:
        raise PresetError(f"missing 'version = {PRESET_VERSION}' at the top of the preset (it says which "
                          "format the file is in)", key="version", source=source)
    v = doc["version"]
    line = where.line("version")
    if isinstance(v, bool) or not isinstance(v, int) or v < 1:
        raise PresetError(f"version = {_short(v)} is not allowed: expected a whole number from 1 to "
                          f"{PRESET_VERSION}", key="version", source=source, line=line)
    if v > PRESET_VERSION:
        raise PresetError(f"version = {v} is newer than this vfiber understands (it reads versions 1 to "
                          f"{PRESET_VERSION}): update vfiber to open this preset", key="version",
                          source=source, line=line)
    return v


def _collect(doc: dict[str, Any]) -> tuple[dict[str, Any], list[tuple[str, str]]]:
    """Flat, checked values and the (key, message) of every problem, in document order."""
    values: dict[str, Any] = {}
    problems: list[tuple[str, str]] = []
    for top, item in doc.items():
        if top in TOP_LEVEL:
            if top in ("name", "description") and not isinstance(item, str):
                problems.append((top, f"{top} = {_short(item)} is not allowed: expected a string"))
            continue
        if top not in GROUPS:
            problems.append((top, _unknown_top(top, item) if len(problems) < MAX_PROBLEMS else ""))
            continue
        if not isinstance(item, dict):
            problems.append((top, f"{top} = {_short(item)} should be a table: write [{top}] and put "
                                  "name = value lines under it"))
            continue
        for name, value in item.items():
            key = f"{top}.{name}"
            if key not in BY_KEY:
                if len(problems) >= MAX_PROBLEMS:  # counted, not described: a "did you mean" costs time
                    problems.append((key, ""))
                    continue
                known = ", ".join(p.name for p in SPEC if p.group == top)
                problems.append((key, f"unknown parameter {key} = {_short(value)}{suggest(key)}; "
                                      f"[{top}] has: {known}"))
                continue
            try:
                values[key] = _check(BY_KEY[key], value)
            except ParamError as e:
                problems.append((key, e.bare))
    return values, problems


def _check(p: Param, value: Any) -> Any:
    return p.check(value)


def _unknown_top(top: str, item: Any) -> str:
    if isinstance(item, dict):
        near = difflib.get_close_matches(top, GROUPS, n=1, cutoff=0.5)
        hint = f" (did you mean [{near[0]}]?)" if near else ""
        return f"unknown table [{top}]{hint}; tables are: {', '.join('[' + g + ']' for g in GROUPS)}"
    homes = [p.group for p in SPEC if p.name == top]  # a parameter written above its table
    hint = f" (put it under [{homes[0]}])" if homes else suggest(top)
    return (f"unknown top-level key {top} = {_short(item)}{hint}; only {', '.join(TOP_LEVEL)} go above "
            "the tables")


def _combine(errors: list[PresetError]) -> PresetError:
    """The first problem by line, then up to MAX_PROBLEMS - 1 more, then how many were left out."""
    described = [e for e in errors if e.bare]
    hidden = len(errors) - len(described)
    described.sort(key=lambda e: (e.line is None, e.line or 0))
    errors = described[:MAX_PROBLEMS]
    hidden += len(described) - len(errors)
    first = errors[0]
    if len(errors) == 1 and not hidden:
        return first
    more = "\n".join(f"  also {e}" for e in errors[1:])
    if hidden:
        more += f"\n  ... and {hidden} more problem{'s' if hidden > 1 else ''} not shown"
    return PresetError(f"{first.bare}\n{more}", key=first.key, source=first.source, line=first.line)


def _short(value: Any) -> str:
    return short_repr(value, _SHORT)


# --------------------------------------------------------------------------------------------------
# saving

def dumps_preset(params: Params, name: str = "", description: str = "") -> str:
    """Every parameter, grouped in SPEC order, each with a comment saying what is allowed.  Writing all
    of them (not just the changed ones) lets an artist see and tweak anything without the docs."""
    if not isinstance(params, Params):
        raise TypeError(f"save_preset needs Params, not {type(params).__name__}")
    head: dict[str, Any] = {"version": PRESET_VERSION}
    if name:
        head["name"] = name
    if description:
        head["description"] = description
    lines = ["# vfiber preset: every parameter is listed; see docs/parameters.md", tomli_w.dumps(head)]
    for group in GROUPS:
        lines.append(f"[{group}]")
        for p in SPEC:
            if p.group == group:
                lines.append(f"{p.name} = {_toml_value(params[p.key])}  # {_allowed_comment(p)}")
        lines.append("")
    return "\n".join(lines)


def _allowed_comment(p: Param) -> str:
    if p.kind is int:  # Param.allowed() prints bounds with %g: a seed's 2147483647 would read 2.14748e+09
        return f"an integer in [{p.lo:.0f}, {p.hi:.0f}]" if p.lo is not None and p.hi is not None \
            else p.allowed()
    return p.allowed()


def _toml_value(value: Any) -> str:
    # tomli_w spreads arrays over several lines; a colour reads better on one.  Floats come out as repr,
    # so they round-trip exactly.
    if isinstance(value, (tuple, list)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    return tomli_w.dumps({"v": value})[len("v = "):].rstrip("\n")


def save_preset(path: str | os.PathLike[str], params: Params, name: str = "",
                description: str = "") -> Path:
    """Write atomically: a crash or a full disk leaves either the old file or the new one, never half of
    one (a temporary file beside the target is fsynced, then renamed over it)."""
    return atomic_write_text(path, dumps_preset(params, name, description))


# --------------------------------------------------------------------------------------------------
# bundled presets

def presets_dir() -> Path | None:
    """The folder of the presets that ship with vfiber.

    pyproject installs the repository's ``presets/`` as package data ``app/presets/``.  This module is
    also called ``app.presets``, so ``importlib.resources.files("app.presets")`` would resolve to this
    .py file (a TypeError on 3.11, the ``app/`` folder on 3.12+); ask for ``app`` and step into
    ``presets`` instead.  In a source checkout that folder does not exist and the top-level one is used.
    """
    candidates: list[Any] = []
    try:
        candidates.append(importlib.resources.files("app").joinpath("presets"))
    except (ModuleNotFoundError, TypeError):
        pass
    candidates.append(Path(__file__).resolve().parents[1] / "presets")
    for c in candidates:
        if c.is_dir():
            return Path(str(c))
    return None


def bundled_presets() -> list[Preset]:
    folder = presets_dir()
    if folder is None:
        return []
    return [load_preset(f) for f in sorted(folder.glob("*.toml"))]


def bundled_names() -> list[str]:
    folder = presets_dir()
    return sorted(f.stem for f in folder.glob("*.toml")) if folder else []


def find_preset(name_or_path: str | os.PathLike[str]) -> Preset:
    """A path if one exists, else a bundled preset by name (file stem, ``.toml`` optional)."""
    path = Path(name_or_path)
    if os.path.lexists(path):  # something is there: load it, or say why it is not a preset
        if path.suffix.lower() != ".toml" and not path.is_dir():
            raise PresetError("not a preset file: a preset is a .toml file (for a groom file use "
                              f"{', '.join(GROOM_SUFFIXES[:-1])} or {GROOM_SUFFIXES[-1]})", source=str(path))
        try:
            path.stat()
        except OSError as e:  # a symbolic link to nowhere, or a loop of them
            raise PresetError(f"cannot open the preset: {e.strerror or e}", source=str(path)) from None
        return load_preset(path)
    folder = presets_dir()
    stem = path.name[:-5] if path.name.endswith(".toml") else path.name
    bare_name = path.name == str(name_or_path)  # "blonde", not "some/dir/blonde"
    if folder is not None and bare_name and (folder / f"{stem}.toml").is_file():
        return load_preset(folder / f"{stem}.toml")
    names = bundled_names()
    near = difflib.get_close_matches(stem, names, n=1)
    hint = f" (did you mean {near[0]!r}?)" if near else ""
    listing = ", ".join(names) if names else "none installed"
    raise PresetError(f"no preset file {str(name_or_path)!r} and no bundled preset of that name{hint}; "
                      f"bundled presets: {listing}", source=str(name_or_path))


# --------------------------------------------------------------------------------------------------
# docs/parameters.md

DEFAULT_PRESET = "default"   # the look a command without a target renders


# A preset is a whole scene; applied to a groom it gives only its look. The look is how fibers fill and shade
# the containers (fibers, shape, look, light); the shot is what the target owns: which containers exist
# (scene), what frames them (camera) and what a frame of them costs (quality: a brute mode or 4x4 supersample
# tuned on one cylinder would make a 150,000-strand groom take minutes, and visibility is picked for a scene's
# density). Every look value is relative to the container it sits in (fiber_radius and curl_amplitude are
# fractions of the container and ring radius, twist and curl count turns per container length), so a look made
# on a generated cylinder means the same on a groom's strand containers.
# A new parameter group must be put in one of the two (tests/test_presets.py fails until it is): strand
# controls such as tip taper or frizz are the look; a control that decides which containers exist is the shot.
LOOK_GROUPS: tuple[str, ...] = ("fibers", "strand", "shape", "look", "light")
SHOT_GROUPS: tuple[str, ...] = ("scene", "camera", "quality")


def look_values(params: Params) -> dict[str, Any]:
    """The look of ``params``: every value of LOOK_GROUPS, the ones a preset left at their default too (a
    look is all of them, so applying ``default`` gives back a groom's own defaults)."""
    return {k: v for k, v in params.values.items() if k.split(".", 1)[0] in LOOK_GROUPS}


def apply_look(target: Params, look: Params) -> Params:
    """``target``'s scene, camera and quality under ``look``'s look (see LOOK_GROUPS)."""
    return Params({**target.values, **look_values(look)})


def is_groom(params: Params) -> bool:
    return params["scene.generator"] == "groom"


def resolve_params(target: str | None, assignments: Iterable[str] = (),
                   look: str | None = None) -> tuple[Params, str]:
    """Params of a command's target -- a preset (name or file) or a groom file -- with ``look`` (``--preset``)
    applied when the target is a groom, then the ``--set`` overrides, and a label saying where they came from
    (for messages). The one way every face (the command line, the exporters, the benches) turns a target into
    parameters.

    ``look`` alone, or equal to ``target``, is the target (``vfiber render --preset curly-1``). With a groom
    (a groom file, or a preset holding one) it is a preset whose look goes onto the groom; the groom keeps its
    scene, camera and quality. Anything else is two scenes at once, an error."""
    if look is None or target is None or look == target:
        values, label = _target_values(target or look)
        return _with_groom_defaults(values, assignments), label
    values, label = _target_values(target)
    if values.get("scene.generator") != "groom":
        raise UsageError(f"two scenes given: {target!r} and --preset {look!r}; --preset puts a preset's look on "
                         f"a groom (a {'/'.join(GROOM_SUFFIXES)} file, or a preset holding one), and {target!r} "
                         "is a scene of its own: give one of them")
    if Path(look).suffix.lower() in GROOM_SUFFIXES:
        raise UsageError(f"two grooms given: {target!r} and --preset {look!r}; --preset takes a look (a preset "
                         f"name or .toml file) to put on the groom {target!r}")
    preset = find_preset(look)
    if is_groom(preset.params):
        raise UsageError(f"--preset {look!r} is itself a groom (scene.groom_file = "
                         f"{preset.params['scene.groom_file']!r}), so with {target!r} there are two grooms; give "
                         f"it alone to see it, or take its look from a preset without a groom file")
    values.update(look_values(preset.params))
    return _with_groom_defaults(values, assignments), f"{label} with the look of {preset.path or look}"


def _with_groom_defaults(values: dict[str, Any], assignments: Iterable[str]) -> Params:
    """``values`` with the ``--set`` assignments, then, when ``fibers.groom_auto`` is on for a groom, the
    groom's own fiber defaults in every key that neither ``values`` (a preset, a look) nor ``--set`` gave."""
    assignments = list(assignments)
    p = with_assignments(values, assignments)
    if p["fibers.groom_auto"] and is_groom(p):
        from .scene.grooms.defaults import groom_defaults

        given = set(values) | {text.split("=", 1)[0].strip() for text in assignments}
        p = groom_defaults(p, given)[0]
    return p


def _target_values(target: str | None) -> tuple[dict[str, Any], str]:
    """(values, label) of a preset or groom file before any ``--set``; no target: the default preset."""
    if target and Path(target).suffix.lower() in GROOM_SUFFIXES:
        if not Path(target).exists():
            raise UsageError(f"{target}: no such groom file")
        return {"scene.generator": "groom", "scene.groom_file": str(Path(target).resolve())}, target
    name = target or (DEFAULT_PRESET if DEFAULT_PRESET in bundled_names() else None)
    if not name:
        return {}, "defaults"
    preset = find_preset(name)
    return groom_relative_to_preset(dict(preset.params.values), preset.path), str(preset.path or name)


def groom_relative_to_preset(values: dict, preset_path: Path | None) -> dict:
    """A relative ``scene.groom_file`` in a preset names a file beside the preset, wherever vfiber runs."""
    groom = values.get("scene.groom_file") or ""
    if groom and preset_path is not None and not Path(groom).is_absolute():
        values["scene.groom_file"] = str(Path(preset_path).parent / groom)
    return values


_TYPE_NAMES = {int: "integer", float: "number", str: "string", bool: "boolean", tuple: "3 numbers"}


def _allowed_md(p: Param) -> str:
    if p.choices:
        return ", ".join(f"`{c}`" for c in p.choices)
    if p.kind is bool:
        return "`true`, `false`"
    if p.kind is str:
        return "any text"
    # integers exactly (a seed's 2147483647 matters), floats short
    def num(x: float | None) -> str:
        return "unbounded" if x is None else str(int(x)) if p.kind is int else f"{x:g}"

    rng = f"{num(p.lo)} … {num(p.hi)}"
    return f"each {rng}" if p.kind is tuple else rng


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def parameters_markdown() -> str:
    """The parameter reference, generated from SPEC so it cannot drift from the code."""
    out = [
        "# Parameters",
        "",
        "<!-- Generated from app/params.py by `python -m app.presets --docs`; do not edit by hand. -->",
        "",
        "Every parameter vfiber understands. In a preset file each one goes in the table of its group; "
        "for example `fibers.rings`:",
        "",
        "```toml",
        f"version = {PRESET_VERSION}",
        'name = "My look"',
        'description = "You should see ..."',
        "",
        "[fibers]",
        "rings = 10",
        "```",
        "",
        "On the command line the same key is set with `--set fibers.rings=10`. Anything left out takes its "
        "default. Colours and points are arrays of 3 numbers, e.g. `color = [0.55, 0.36, 0.2]`.",
        "",
        "Rules between parameters:",
        "",
        f"- `fibers.fiber_radius` must be at most 0.5 / `fibers.rings` (a fiber fits its ring; with the "
        f"default 10 rings that is {max_fiber_radius(10):g}).",
        "- `scene.generator = \"groom\"` needs `scene.groom_file`.",
        "",
        f"Preset format version: {PRESET_VERSION}. Older files are migrated when loaded; version 1 had one "
        "`[params]` table with `internal_cylinders`, `phi_step`, `phi_step_increment`, `jitter` and "
        "`fiber_radius`.",
        "",
    ]
    for group in GROUPS:
        out += [f"## [{group}]", "", "| key | type | default | allowed | unit | help |",
                "|---|---|---|---|---|---|"]
        for p in SPEC:
            if p.group != group:
                continue
            default = _toml_value(p.default)
            out.append(f"| `{p.key}` | {_TYPE_NAMES[p.kind]} | `{_cell(default)}` | {_cell(_allowed_md(p))} "
                       f"| {p.unit} | {_cell(p.help)} |")
        out.append("")
    return "\n".join(out)


def main(argv: Iterable[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m app.presets", description=(__doc__ or "").split("\n")[0])
    ap.add_argument("--docs", action="store_true", help=f"write {DOCS_PATH.name} from app/params.py")
    ap.add_argument("--check", action="store_true", help="exit 1 if the docs are out of date")
    ap.add_argument("files", nargs="*", help="preset files or bundled names to validate")
    args = ap.parse_args(list(argv) if argv is not None else None)
    status = 0
    if args.docs or args.check:
        text = parameters_markdown()
        current = DOCS_PATH.read_text(encoding="utf-8") if DOCS_PATH.exists() else ""
        if args.check:
            if current != text:
                print(f"{DOCS_PATH} is out of date: run python -m app.presets --docs", file=sys.stderr)
                status = 1
        elif current != text:
            DOCS_PATH.parent.mkdir(parents=True, exist_ok=True)
            DOCS_PATH.write_text(text, encoding="utf-8")
            print(f"wrote {DOCS_PATH}")
    for name in args.files:
        try:
            preset = find_preset(name)
            print(f"{preset.path}: ok ({preset.name})")
        except PresetError as e:
            print(e, file=sys.stderr)
            status = 1
    return status


if __name__ == "__main__":
    sys.exit(main())
