"""Values the knowledge-base tools return: query results, proof trees, diagnostics, docs."""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

from ita.errors import Location


@dataclass(frozen=True)
class QueryResult:
    """The answers to a user query.

    `variables` are the query's named variables (those not starting with ``_``), in
    order of appearance; each row holds one solution's values printed as Prolog text
    (``format("~q")``), one per variable.  A goal without variables that succeeds has one
    empty row.  `truncated` is True when more solutions exist beyond the limit.
    """

    goal: str
    variables: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    truncated: bool = False

    @property
    def succeeded(self) -> bool:
        """True when the goal has at least one solution."""
        return bool(self.rows)


@dataclass(frozen=True)
class ProofNode:
    """One step of a proof: a goal, how it was proved, and the proofs of its subgoals.

    `kind` is ``query`` (the root), ``rule`` or ``fact`` (a clause of a knowledge base,
    at `location`), ``builtin`` (a library or engine predicate, taken as given),
    ``negation`` (``\\+ G``: G has no proof), or ``depth_limit`` (not expanded further).
    """

    goal: str
    kind: str
    location: Location | None
    children: tuple["ProofNode", ...] = ()


class Severity(Enum):
    """How bad a diagnostic is."""

    ERROR = "error"
    WARNING = "warning"


@dataclass(frozen=True)
class Diagnostic:
    """A problem found while loading or checking the knowledge bases."""

    severity: Severity
    location: Location
    message: str

    def __str__(self) -> str:
        return f"{self.location}: {self.severity.value}: {self.message}"


@dataclass(frozen=True)
class PredicateDoc:
    """An exported predicate of a knowledge-base file and the first line of its PlDoc."""

    module: str
    name: str
    arity: int
    file: str
    mode: str
    summary: str

    @property
    def indicator(self) -> str:
        """``module:name/arity``."""
        return f"{self.module}:{self.name}/{self.arity}"
