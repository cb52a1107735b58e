"""Attached procedures: Python functions that answer Prolog goals.

Prolog code (the HTN planner's method preconditions, say) calls special-purpose Python
functions as tools through one goal, ``py_bridge:attached(Name, Args, Result)`` (see
prolog/py_bridge.pl).  The function attached under ``Name`` receives the terms of
``Args`` as Python values (:data:`~ita.logic.terms.TermValue`) and gives its solutions:

- a plain function is *semidet*: it returns one solution, or ``None`` for none
  (the goal fails);
- a function wrapped by :func:`nondet` returns an iterable of solutions, each a
  solution of the goal on backtracking (the iterable is read to its end before the
  first one is returned, so it must be finite).

An exception raised by the function becomes a Prolog exception that names the
procedure, and a :class:`~ita.errors.PrologError` for the Python code that ran the
outer goal.

Procedures are attached for the duration of a ``with`` block, and only for the goals
that the thread which entered the block runs::

    with kb.attached({"next_step": next_step, "tours": nondet(tours)}):
        kb.call("htn", "plan", task, Var("Plan"))

:class:`AttachedProcedures` keeps those scopes; it knows nothing of Prolog (the
bridge, ita.logic.bridge, calls :meth:`AttachedProcedures.solutions`).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TypeAlias

from ita.logic.terms import Str, Term, TermValue

__all__ = ["AttachedProcedures", "Nondet", "Procedure", "nondet"]


@dataclass(frozen=True)
class Nondet:
    """An attached procedure whose function returns all its solutions (an iterable)."""

    function: Callable[..., Iterable[TermValue] | None]


def nondet(function: Callable[..., Iterable[TermValue] | None]) -> Nondet:
    """Mark `function` as a nondeterministic attached procedure: it returns an
    iterable of solutions (``None`` or an empty one: the goal fails)."""
    if not callable(function):
        raise TypeError(f"an attached procedure must be callable, got {function!r}")
    return Nondet(function)


#: What can be attached: a function returning one solution or None (semidet), or a
#: :class:`Nondet` whose function returns an iterable of solutions.
Procedure: TypeAlias = Callable[..., TermValue | None] | Nondet


class AttachedProcedures:
    """The procedures attached in each thread: a stack of scopes, the innermost first.

    A name attached in an inner scope hides the same name of an outer one until the
    inner scope ends.  Another thread sees none of them.
    """

    def __init__(self) -> None:
        self._local = threading.local()

    def _scopes(self) -> list[dict[str, Procedure]]:
        scopes: list[dict[str, Procedure]] | None = getattr(self._local, "scopes", None)
        if scopes is None:
            scopes = self._local.scopes = []
        return scopes

    @contextmanager
    def scope(self, procedures: Mapping[str, Procedure]) -> Iterator[None]:
        """Attach `procedures` (name -> function or :class:`Nondet`) in this thread
        until the block ends.  TypeError for a name that is not a non-empty str or a
        value that is not callable."""
        scope: dict[str, Procedure] = {}
        for name, procedure in procedures.items():
            if not isinstance(name, str) or not name:
                raise TypeError(f"an attached procedure needs a non-empty str name, got {name!r}")
            if not (isinstance(procedure, Nondet) or callable(procedure)):
                raise TypeError(f"attached procedure {name!r} must be callable, got {procedure!r}")
            scope[str.__str__(name)] = procedure
        scopes = self._scopes()
        scopes.append(scope)
        try:
            yield
        finally:
            # by identity: scopes of interleaved generators may end out of order
            for i in range(len(scopes) - 1, -1, -1):
                if scopes[i] is scope:
                    del scopes[i]
                    break

    def find(self, name: str) -> Procedure | None:
        """The procedure attached under `name` in this thread, or None."""
        scopes: list[dict[str, Procedure]] | None = getattr(self._local, "scopes", None)
        for scope in reversed(scopes or ()):
            procedure = scope.get(name)
            if procedure is not None:
                return procedure
        return None

    @staticmethod
    def solutions(procedure: Procedure, args: Iterable[TermValue]) -> list[TermValue]:
        """The solutions of `procedure` called on `args`: [] (fail), one, or many.
        Whatever the function raises propagates; TypeError when a nondet function
        returns something that is not a collection of solutions."""
        if isinstance(procedure, Nondet):
            found = procedure.function(*args)
            if found is None:
                return []
            if isinstance(found, (str, bytes, Str, Term, Mapping)):
                raise TypeError(f"a nondet procedure returns an iterable of solutions, "
                                f"got {type(found).__name__} {found!r}")
            return list(found)
        value = procedure(*args)
        return [] if value is None else [value]
