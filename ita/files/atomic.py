"""Writes that never destroy, and read-modify-write under a lock.

:func:`write_atomic` is the one way ITA writes a file a person names (``report -o``,
``spec export``, ``part render -o``...) and its own stores: the content goes to a
temporary file in the same directory, is flushed to disk, and replaces the target in one
rename.  Before anything is written the target is checked (:func:`output_path`):

- an empty name is an error;
- a symbolic link is followed, and what it points to is the target;
- a target that exists and is not a regular file (a device such as ``/dev/full``, a
  FIFO, a socket, a directory) is refused: a rename would replace it;
- a missing directory is created only when the caller asks (``make_dirs``), else it is
  an error naming the directory;
- a directory that cannot be written is an error naming it.

Every refusal is an :class:`~ita.errors.InputError` naming the file (exit code 2), and
nothing is written.  A write that fails (a full disk: :class:`~ita.errors.NoSpaceLeft`,
"FILE: no space left on device") removes its temporary file and leaves the target as it
was.  :func:`locked` serialises read-modify-write cycles of a store
(``specs.csv``...) between processes with ``fcntl.flock`` on a lock file beside it.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import stat
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from ita.errors import InputError, Location, NoSpaceLeft

__all__ = ["output_path", "write_atomic", "write_json_atomic", "write_with", "locked", "store_name"]


def _refuse(path: Path | str, what: str, message: str) -> InputError:
    return InputError([(Location(str(path), field=what), message)])


def output_path(path: Path | str, *, what: str = "", make_dirs: bool = False) -> Path:
    """The file a write to `path` will replace, checked (see the module comment).

    `what` names the option or argument in messages (e.g. ``-o``).  With `make_dirs`,
    missing parent directories are created."""
    if isinstance(path, str) and not path.strip():
        raise _refuse("''", what, "empty file name; give the file to write")
    path = Path(path)
    if str(path) in ("", "."):
        raise _refuse("''", what, "empty file name; give the file to write")
    if path.is_symlink():
        path = Path(os.path.realpath(path))
    try:
        info = path.stat()
    except (FileNotFoundError, NotADirectoryError):
        info = None
    except OSError as exc:
        raise _refuse(path, what, f"cannot look at it: {exc.strerror}") from None
    if info is not None and not stat.S_ISREG(info.st_mode):
        kind = _kind(info.st_mode)
        raise _refuse(path, what, f"exists and is {kind}, not a regular file; refusing to replace it")
    parent = path.parent
    if not parent.is_dir():
        if parent.exists():
            raise _refuse(parent, what, "is not a directory")
        if not make_dirs:
            raise _refuse(parent, what, "directory does not exist (create it first)")
        try:
            parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise _refuse(parent, what, f"cannot create the directory: {exc.strerror}") from None
    if not os.access(parent, os.W_OK | os.X_OK):
        raise _refuse(parent, what, "directory is not writable")
    return path


def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISFIFO(mode):
        return "a FIFO"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def write_atomic(path: Path | str, content: str | bytes, *, what: str = "",
                 make_dirs: bool = False) -> Path:
    """Write `content` (text as UTF-8) to `path` atomically; returns the file written."""
    data = content.encode("utf-8") if isinstance(content, str) else content

    def dump(tmp: Path) -> None:
        with open(tmp, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())

    return write_with(path, dump, what=what, make_dirs=make_dirs)


def write_json_atomic(path: Path | str, data: Any, *, what: str = "") -> Path:
    """Write `data` as JSON (indented, one trailing newline) to `path` atomically, making
    its directory when missing (a store); returns the file written."""
    return write_atomic(path, json.dumps(data, indent=1) + "\n", what=what, make_dirs=True)


def store_name(name: str) -> str:
    """`name` (a part's) as a file name of a store: letters, digits, ``-``, ``_`` and
    ``.`` kept, anything else ``_`` (``part`` when nothing is left)."""
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in name) or "part"


def write_with(path: Path | str, writer: Callable[[Path], object], *, what: str = "",
               make_dirs: bool = False, suffix: str = ".tmp") -> Path:
    """Call `writer` on a temporary file beside `path`, then rename it over `path`.

    For writers that want a file name (matplotlib's savefig...).  `suffix` is the
    temporary file's ending.  On any error the temporary file is removed and the target
    is untouched; an OSError becomes an InputError naming the file."""
    target = output_path(path, what=what, make_dirs=make_dirs)
    try:
        fd, name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=suffix, dir=target.parent)
    except OSError as exc:
        raise _refuse(target.parent, what, f"cannot write there: {exc.strerror}") from None
    os.close(fd)
    tmp = Path(name)
    try:
        with contextlib.suppress(OSError):
            os.chmod(tmp, _mode_for(target))
        writer(tmp)
        os.replace(tmp, target)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        full = NoSpaceLeft.of_errno(str(target), exc.errno)
        if full is not None:
            raise full from None
        raise _refuse(target, what, f"cannot write it: {exc.strerror or exc}") from None
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    with contextlib.suppress(OSError):
        dir_fd = os.open(target.parent, os.O_RDONLY)
        try:
            os.fsync(dir_fd)
        finally:
            os.close(dir_fd)
    return target


def _mode_for(target: Path) -> int:
    """The permission bits of the file being replaced, or 0o666 less the umask."""
    try:
        return stat.S_IMODE(target.stat().st_mode)
    except OSError:
        mask = os.umask(0)
        os.umask(mask)
        return 0o666 & ~mask


@contextlib.contextmanager
def locked(path: Path | str) -> Iterator[None]:
    """Hold an exclusive lock for a read-modify-write of `path` (another process that
    asks for the same lock waits).  The lock file is ``.<name>.lock`` beside it."""
    path = Path(path)
    lock = path.with_name(f".{path.name}.lock")
    try:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666)
    except OSError as exc:
        raise _refuse(path, "", f"cannot lock it for a change ({lock}): {exc.strerror}") from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        with contextlib.suppress(OSError):
            fcntl.flock(fd, fcntl.LOCK_UN)
        os.close(fd)
