"""Writing a user's file so that a crash, a full disk or an exception never loses the old one.

The new content goes to a temporary file beside the target (``.NAME.<pid>.<random>.tmp``), which is fsynced
and renamed over the target. A process killed in between leaves its temporary file behind; the pid in the
name lets the next save of the same file remove the ones whose process is gone.

Saving follows a symbolic link (the link stays, its target gets the new content), refuses a read-only
file rather than replacing it, and reports every failure as a :class:`SaveError` naming the target.
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import stat
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

from .errors import VfiberError

STALE_UNKNOWN_S = 3600  # a temporary file without a pid (older vfiber) is stale after an hour
_active: set[str] = set()  # temporary files being written now, for remove_active_temporaries


class SaveError(VfiberError, OSError):
    """A file could not be written; ``str(e)`` is one line naming the file the person asked for."""

    def __init__(self, path: Path | str, why: str, code: int | None = None):
        super().__init__(code or 0, why)
        self.filename = str(path)
        self.message = f"{path}: {why}"

    def __str__(self) -> str:
        return self.message


def save_target(path: str | os.PathLike[str]) -> Path:
    """The file a save of ``path`` really writes: the end of a chain of symbolic links, checked to be
    writable. Raises SaveError for a folder, a read-only file, or a link that leads nowhere usable."""
    path = Path(path)
    target = Path(os.path.realpath(path)) if path.is_symlink() else path
    if target.is_dir():
        raise SaveError(path, "is a folder: give a file name", errno.EISDIR)
    if target.exists():
        mode = target.stat().st_mode
        if not stat.S_ISREG(mode):
            raise SaveError(path, "is not a regular file: not replaced", errno.EINVAL)
        # no write bit at all is a person's "do not overwrite", which root's access() would ignore
        if not os.access(target, os.W_OK) or not mode & 0o222:
            raise SaveError(path, f"is read-only (mode {stat.S_IMODE(mode):04o}): not overwritten; make it "
                                  "writable (chmod u+w) or save under another name", errno.EACCES)
    folder = target.parent if str(target.parent) else Path(".")
    if not folder.is_dir():
        raise SaveError(path, f"folder {folder} does not exist", errno.ENOENT)
    return target


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; when the block succeeds the file is fsynced and renamed
    over ``path`` (keeping the old file's mode), otherwise it is removed and ``path`` is untouched.
    OSErrors while writing become SaveError naming ``path`` (not the hidden temporary file)."""
    asked = Path(path)
    path = save_target(asked)
    directory = path.parent if str(path.parent) else Path(".")
    remove_stale_temporaries(path)
    try:
        fd, tmp = tempfile.mkstemp(dir=directory, prefix=f".{path.name}.{os.getpid()}.", suffix=".tmp")
    except OSError as e:
        raise SaveError(asked, f"cannot write in folder {directory}: {e.strerror or e}", e.errno) from None
    os.close(fd)
    _active.add(tmp)
    try:
        yield Path(tmp)
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
        try:  # mkstemp makes 0600; keep the old file's mode, or a normal one
            os.chmod(tmp, path.stat().st_mode & 0o7777 if path.exists() else 0o644)
        except OSError:
            pass
        os.replace(tmp, path)
    except BaseException as e:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(e, OSError) and not isinstance(e, SaveError):
            if e.errno == errno.ENOSPC:
                raise SaveError(asked, f"the disk is full ({e.strerror}): nothing was written, any old file "
                                       "is kept", e.errno) from None
            raise SaveError(asked, f"cannot be written ({e.strerror or e}); any old file is kept",
                            e.errno) from None
        raise
    finally:
        _active.discard(tmp)
    _fsync_dir(directory)  # make the rename itself durable


def remove_active_temporaries() -> None:
    """Remove the temporary files of saves under way: for a process about to exit at once (Ctrl-C)."""
    for tmp in list(_active):
        try:
            os.unlink(tmp)
        except OSError:
            pass


def atomic_write_text(path: str | os.PathLike[str], text: str) -> Path:
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8", newline="\n")
    return Path(path)


def remove_stale_temporaries(path: str | os.PathLike[str]) -> list[Path]:
    """Remove the temporary files earlier saves of ``path`` left when they were killed: those whose
    process no longer runs (or, without a pid in the name, older than STALE_UNKNOWN_S). Returns them."""
    path = Path(path)
    directory = path.parent if str(path.parent) else Path(".")
    removed: list[Path] = []
    try:
        candidates = list(directory.glob(f".{glob_escape(path.name)}.*.tmp"))
    except OSError:
        return removed
    pattern = re.compile(rf"^\.{re.escape(path.name)}\.(?:(?P<pid>\d+)\.)?[A-Za-z0-9_]{{8}}\.tmp$")
    for tmp in candidates:
        m = pattern.match(tmp.name)
        if not m:
            continue
        try:
            stale = (not _alive(int(m["pid"]))) if m["pid"] else \
                time.time() - tmp.lstat().st_mtime > STALE_UNKNOWN_S
            if stale and tmp.is_file() and not tmp.is_symlink():
                tmp.unlink()
                removed.append(tmp)
        except OSError:
            pass
    return removed


def glob_escape(name: str) -> str:
    return re.sub(r"([*?\[])", r"[\1]", name)


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True  # another save in this process may be under way
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError, OSError):
        return True  # someone else's process: leave its file alone
    return True


def _fsync_dir(directory: Path) -> None:
    if not hasattr(os, "O_DIRECTORY"):  # Windows cannot open a directory; its rename is durable enough
        return
    try:
        fd = os.open(directory, os.O_RDONLY | os.O_DIRECTORY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)
