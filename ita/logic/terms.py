"""Prolog terms as Python values, and their JSON encoding for the bridge.

Python values map to Prolog terms as follows (both directions, see prolog/py_bridge.pl):
``str`` <-> atom, ``int``/``float`` <-> number, ``list`` <-> list, :class:`Term` <->
compound, :class:`Var` <-> variable, :class:`Str` -> string (strings come back as ``str``).
``True``/``False`` become the atoms ``true``/``false``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Var:
    """A Prolog variable; variables with the same name are the same variable."""

    name: str

    def __post_init__(self) -> None:
        if not self.name:
            raise ValueError("a variable needs a name")


@dataclass(frozen=True)
class Term:
    """A compound term ``name(args...)``, e.g. ``Term("in_rack", ("slot_1",))``."""

    name: str
    args: tuple[Any, ...]

    def __post_init__(self) -> None:
        if not self.args:
            raise ValueError(f"compound {self.name!r} needs at least one argument; use a str for an atom")
        object.__setattr__(self, "args", tuple(self.args))


@dataclass(frozen=True)
class Str:
    """A Prolog string (rather than an atom) to pass as an argument."""

    text: str


def to_json(value: Any) -> Any:
    """Encode a Python value as the JSON structure py_bridge.pl reads as a term."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (str, int, float)):
        return value
    if isinstance(value, Var):
        return {"var": value.name}
    if isinstance(value, Str):
        return {"str": value.text}
    if isinstance(value, Term):
        return {"functor": value.name, "args": [to_json(a) for a in value.args]}
    if isinstance(value, (list, tuple)):
        return [to_json(v) for v in value]
    raise TypeError(f"cannot pass {type(value).__name__} {value!r} to Prolog")


def from_json(data: Any) -> Any:
    """Decode the JSON structure py_bridge.pl writes for a term into Python values."""
    if isinstance(data, list):
        return [from_json(v) for v in data]
    if isinstance(data, dict):
        if "var" in data:
            return Var(data["var"])
        if "functor" in data:
            return Term(data["functor"], tuple(from_json(a) for a in data["args"]))
        raise ValueError(f"unexpected term encoding {data!r}")
    return data
