"""Every error meant for a person derives from app.errors.VfiberError (and still from the builtin it always
was), and the command line turns exactly those into their own one-line message."""

from __future__ import annotations

import ast
import builtins
import importlib

import pytest

from app.cli import describe_error
from app.errors import UsageError, VfiberError
from tests.support.paths import ROOT

APP = ROOT / "app"
# Exception classes of app/ that are not for a person, each with the reason. Empty today.
NOT_FOR_PEOPLE: dict[str, str] = {}


def _exception_classes() -> list[tuple[str, str]]:
    """(module, class) of every class in app/ whose bases name an exception: a builtin one or a class of
    this list (found by name, so a subclass of ParamError defined anywhere is found too)."""
    found: list[tuple[str, str, list[str]]] = []
    for path in sorted(APP.rglob("*.py")):
        module = ".".join(path.relative_to(APP.parent).with_suffix("").parts).removesuffix(".__init__")
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ClassDef):
                bases = [b.attr if isinstance(b, ast.Attribute) else getattr(b, "id", "") for b in node.bases]
                found.append((module, node.name, bases))
    builtin = {n for n, v in vars(builtins).items() if isinstance(v, type) and issubclass(v, BaseException)}
    names = set(builtin)
    while True:   # close over subclasses of our own exception classes
        more = {name for _, name, bases in found if set(bases) & names} - names
        if not more:
            break
        names |= more
    return [(m, c) for m, c, bases in found if set(bases) & names]


CLASSES = _exception_classes()


def test_the_scan_finds_the_known_errors():
    got = {c for _, c in CLASSES}
    assert {"ParamError", "PresetError", "GroomError", "ShaderError", "ShaderCompileError", "GLContextError",
            "UsageError", "ExplicitBudgetError", "SaveError", "ScriptError", "BlenderRenderError"} <= got, got


@pytest.mark.parametrize("module,name", CLASSES, ids=[f"{m}.{c}" for m, c in CLASSES])
def test_every_error_class_is_a_vfiber_error(module, name):
    cls = getattr(importlib.import_module(module), name)   # importable where it always was
    if name in NOT_FOR_PEOPLE:
        pytest.skip(NOT_FOR_PEOPLE[name])
    assert issubclass(cls, VfiberError), f"{module}.{name} is meant for a person: derive it from VfiberError"


@pytest.mark.parametrize("module,name,builtin", [
    ("app.params", "ParamError", ValueError), ("app.presets", "PresetError", ValueError),
    ("app.scene.grooms", "GroomError", ValueError), ("app.gl.shaders", "ShaderError", RuntimeError),
    ("app.gl.context", "GLContextError", RuntimeError), ("app.render.explicit", "ExplicitBudgetError", MemoryError),
    ("app.atomic", "SaveError", OSError), ("app.cli", "UsageError", ValueError),
    ("app.export.osl", "UsageError", ValueError), ("app.viewer.script", "ScriptError", ValueError),
])
def test_errors_keep_their_builtin_base_so_old_except_clauses_still_catch_them(module, name, builtin):
    assert issubclass(getattr(importlib.import_module(module), name), builtin)


def test_usage_error_is_one_class_wherever_it_is_imported_from():
    import app.cli
    import app.export.osl

    assert app.cli.UsageError is app.export.osl.UsageError is UsageError


def test_describe_error_shows_a_persons_error_as_it_is_and_a_bug_as_a_bug():
    from app.atomic import SaveError
    from app.render.explicit import ExplicitBudgetError
    from app.viewer.script import ScriptError

    for e in (UsageError("--size 'x': expected WIDTHxHEIGHT"), ScriptError("step 3: unknown option 'x'"),
              SaveError("out.png", "permission denied", 13), ExplicitBudgetError(10, 1, 5, 2.0),
              FileNotFoundError(2, "No such file or directory")):
        assert describe_error(e) == str(e)

    class Bug(VfiberError.__base__):   # Exception, but not a VfiberError
        pass

    for e in (KeyError("k"), Bug("b"), ValueError("v")):
        text = describe_error(e)
        assert text.startswith(f"unexpected error: {type(e).__name__}: ") and "VFIBER_DEBUG=1" in text
