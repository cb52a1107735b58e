"""The project's own exceptions.  Every error a user can cause names what and where."""

from __future__ import annotations

import errno
import os
from dataclasses import dataclass


class ItaError(Exception):
    """Base class for ITA errors that a user can act on (the CLI prints them, exit code 2)."""

    exit_code = 2


class ItaWarning(UserWarning):
    """Base class for ITA's warnings: something a user should know that does not stop the
    command (the CLI prints each as one line, `warning: ...`)."""


@dataclass(frozen=True)
class Location:
    """Where in a file something went wrong (1-based line and column; 0 when unknown)."""

    file: str
    line: int = 0
    column: int = 0
    field: str = ""

    def __str__(self) -> str:
        text = self.file
        if self.line:
            text += f":{self.line}"
            if self.column:
                text += f":{self.column}"
        if self.field:
            text += f" [{self.field}]"
        return text


class InputError(ItaError):
    """Bad user input; carries one or more (location, message) problems."""

    def __init__(self, problems: list[tuple[Location, str]]):
        self.problems = list(problems)
        super().__init__("\n".join(f"{loc}: {msg}" for loc, msg in self.problems))


class PrologError(ItaError):
    """A Prolog goal raised an error; carries the goal and Prolog's message."""

    def __init__(self, goal: str, message: str):
        self.goal = goal
        self.message = message
        super().__init__(f"{goal}: {message}")


class KBLoadError(ItaError):
    """A Prolog file of prolog/ or kb/ failed to load; names file, line and column."""

    def __init__(self, problems: list[tuple[Location, str]]):
        self.problems = list(problems)
        super().__init__(
            "knowledge base failed to load:\n"
            + "\n".join(f"  {loc}: {msg}" for loc, msg in self.problems)
        )


class QueryRefused(ItaError):
    """A user goal was refused by the sandbox (unsafe) or could not be parsed."""


class QueryLimitExceeded(ItaError):
    """A user goal ran past its time or inference limit."""


#: errno -> what a write that failed with it says: the disk, the quota or the file-size limit is full
_FULL = {errno.ENOSPC: "no space left on device", errno.EDQUOT: "no space left on device (disk quota exceeded)",
         errno.EFBIG: "no space left for it: file too large (the file-size limit, ulimit -f)"}


class NoSpaceLeft(ItaError):
    """A write failed for want of room: the file system or the quota is full, or the
    file-size limit was reached.  Names the file; whoever wrote it has removed what it left."""

    def __init__(self, file: str, detail: str = _FULL[errno.ENOSPC]):
        self.file = file
        super().__init__(f"{file}: {detail}")

    @classmethod
    def of_errno(cls, file: str, code: int | None) -> NoSpaceLeft | None:
        """The error for a write to `file` that failed with errno `code`; None when that
        errno is not about room (a permission, a missing directory ...)."""
        return cls(file, _FULL[code]) if code is not None and code in _FULL else None

    @classmethod
    def of_message(cls, file: str, message: str) -> NoSpaceLeft | None:
        """The error for a write to `file` whose failure `message` quotes the system's
        reason (SWI-Prolog's I/O errors do: "... (No space left on device)"); None when
        the reason is not about room."""
        for code, detail in _FULL.items():
            if os.strerror(code) in message:
                return cls(file, detail)
        return None
