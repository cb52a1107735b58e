"""The project's own exceptions.  Every error a user can cause names what and where."""

from __future__ import annotations

from dataclasses import dataclass


class ItaError(Exception):
    """Base class for ITA errors that a user can act on (the CLI prints them, exit code 2)."""

    exit_code = 2


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
