"""Errors meant for a person: one base class, so every face (CLI, viewer, export) can tell them apart from bugs.

``str(e)`` of a :class:`VfiberError` is the whole message a person reads: it names the file, key or option,
the value and what is allowed. Anything else that reaches a face is a bug and is reported as one.

Each error keeps its home next to the code that raises it (``ParamError`` in app.params, ``GroomError`` in
app.scene.grooms, ...) and also derives from the builtin it always was (ValueError, RuntimeError, OSError,
MemoryError), so ``except ValueError`` in a caller still catches it. Only :class:`UsageError` lives here: the
command line and the exporters share it, and defining it in app.cli made them import each other.
"""

from __future__ import annotations


class VfiberError(Exception):
    """Base of every error a person can cause and fix; ``str(e)`` is the message to show them."""


class UsageError(VfiberError, ValueError):
    """A command-line mistake the user can fix."""
