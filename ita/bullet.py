"""Import pybullet without the "pybullet build time: ..." line its C module prints on
stdout when it is first imported (the line is not ours to show a user)."""

from __future__ import annotations

import os
import sys
from types import ModuleType


def import_pybullet() -> ModuleType:
    """The pybullet module, imported with file descriptors 1 and 2 pointed at /dev/null
    for the moment of the import (Python's own streams are flushed first)."""
    if "pybullet" in sys.modules:
        return sys.modules["pybullet"]
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (AttributeError, ValueError):
            pass
    saved: list[int] = []
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        for fd in (1, 2):
            saved.append(os.dup(fd))
            os.dup2(null, fd)
        import pybullet

        try:
            libc_flush = __import__("ctypes").CDLL(None).fflush
            libc_flush(None)           # the C library's stdout buffer, while it still points at /dev/null
        except (OSError, AttributeError):
            pass
    finally:
        for fd, old in zip((1, 2), saved):
            os.dup2(old, fd)
            os.close(old)
        os.close(null)
    return pybullet
