"""Prolog terms as Python values, and the reading of the bridge's replies.

Python values map to Prolog terms as follows (both directions, see ita/logic/bridge.py
and prolog/py_bridge.pl): ``str`` <-> atom, ``int``/``float`` <-> number (big integers,
``inf`` and ``nan`` included), ``list`` <-> list, :class:`Term` <-> compound,
:class:`Var` <-> variable, :class:`Str` -> string (strings come back as ``str``).
``True``/``False`` become the atoms ``true``/``false``; tuples are passed as lists.

The bridge builds the terms it sends with SWI-Prolog's C interface.  Prolog writes
its answers back as text, quoted and without operators (``write_term/2`` with
``quoted(true), ignore_ops(true)``), and :func:`read_term` parses that text: one
regular expression finds the tokens, a loop builds the values.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any, TypeAlias, Union

__all__ = ["Str", "Term", "TermValue", "Var", "read_term"]


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
    #: the arguments, each a :data:`TermValue`, left dynamically typed: code that reads a decoded term
    #: knows its shape from the knowledge base (``choice(Id, use(Class, Tool, Rule), Why)``)
    #: and unpacks its arguments as such without narrowing each one first.
    args: tuple[Any, ...]

    def __post_init__(self) -> None:
        if not self.args:
            raise ValueError(f"compound {self.name!r} needs at least one argument; use a str for an atom")
        object.__setattr__(self, "args", tuple(self.args))


@dataclass(frozen=True)
class Str:
    """A Prolog string (rather than an atom) to pass as an argument."""

    text: str


#: A Prolog term as a Python value (see the module docstring): what :func:`read_term`
#: decodes (``str``, ``int``, ``float``, :class:`Term`, :class:`Var`, ``list`` of terms)
#: and what the bridge passes to Prolog (also :class:`Str`, and tuples as lists).
TermValue: TypeAlias = Union[str, int, float, Term, Var, Str, Sequence["TermValue"]]


# -- Prolog text -> Python ------------------------------------------------------------

# The tokens of the text SWI-Prolog's write_term/2 produces with quoted(true),
# ignore_ops(true), dotlists(false), brace_terms(false), numbervars(false): a blob
# such as <stream>(0x...); a bare token (unquoted atom, number, variable) or a quoted
# atom, each with the "(" that makes it a compound's name; punctuation; a string.
# Commas need no token.  Every other character is a token of its own, which read_term
# refuses.
_QUOTED = r"{q}[^{q}\\]*(?:(?:\\(?:x[0-9a-fA-F]+\\|[0-7]+\\|.)|{q}{q})[^{q}\\]*)*{q}"
_TOKENS = re.compile(
    r"<[a-z_]+>\(0x[0-9a-fA-F]+\)"
    r"|[^\s()\[\],|'\"]+\(?"
    r"|[\[\])|]"
    r"|" + _QUOTED.format(q="'") + r"\(?"
    r"|" + _QUOTED.format(q='"') +
    r"|[^\s,]",
    re.DOTALL,
)
_ESCAPE = re.compile(r"\\(?:x([0-9a-fA-F]+)\\|([0-7]+)\\|u([0-9a-fA-F]{4})|U([0-9a-fA-F]{8})|(.))|('')|(\"\")", re.DOTALL)
_SIMPLE_ESCAPES = {
    "n": "\n", "t": "\t", "r": "\r", "a": "\a", "b": "\b", "f": "\f", "v": "\v",
    "0": "\0", "e": "\x1b", "s": " ", "z": "", "\n": "",
}
_NUMBER = re.compile(r"-?\d")
_SPECIAL_FLOAT = re.compile(r"(-?)\d+\.\d+(Inf|NaN)\Z")
_RATIONAL = re.compile(r"-?\d+r\d+\Z")
_LOWER = frozenset("abcdefghijklmnopqrstuvwxyz")


def _unescape_one(match: re.Match[str]) -> str:
    hexa, octal, u4, u8, char, squote, dquote = match.groups()
    if squote:
        return "'"
    if dquote:
        return '"'
    code = hexa or u4 or u8
    if code:
        return chr(int(code, 16))
    if octal:
        return chr(int(octal, 8))
    return _SIMPLE_ESCAPES.get(char, char)


def _unescape(body: str) -> str:
    return _ESCAPE.sub(_unescape_one, body) if "\\" in body or "''" in body or '""' in body else body


def _number(token: str) -> int | float:
    """A number as SWI-Prolog writes it: ``12``, ``-1.5e-7``, ``1.0Inf``, ``1.5NaN``, ``1r3``."""
    if token.isdigit() or (token[1:].isdigit() and token[0] == "-"):
        return int(token)
    if "I" not in token and "N" not in token and "r" not in token:
        return float(token)  # 1.5, -0.0, 1.0e+20 (Prolog always writes the dot)
    special = _SPECIAL_FLOAT.match(token)
    if special:
        if special.group(2) == "NaN":
            return math.nan
        return -math.inf if special.group(1) else math.inf
    if _RATIONAL.match(token):
        return float(Fraction(token.replace("r", "/")))
    raise ValueError(f"not a number: {token!r}")


def read_term(text: str) -> TermValue:
    """The Python value of a term that Prolog wrote quoted and without operators.

    Atoms and strings become ``str``, numbers ``int``/``float``, proper lists ``list``,
    other compounds :class:`Term` (a partial list ``[a|T]`` is ``'[|]'(a, T)``) and
    variables :class:`Var` named as Prolog printed them.  Raises ValueError for text
    that is not such a term (a dict, say).
    """
    # (enclosing items, the compound's name or None for an open list)
    stack: list[tuple[list[TermValue], str | None]] = []
    items: list[TermValue] = []
    tails: list[int] = []                     # depths of the open lists that have a '|'
    for token in _TOKENS.findall(text):
        first = token[0]
        if first in _LOWER:  # the commonest token: an atom, or a compound's name
            if token[-1] == "(":
                stack.append((items, token[:-1]))
                items = []
            elif "{" in token:
                raise ValueError(f"cannot read a dict: {token!r}")
            else:
                items.append(token)
        elif first == "]":
            outer, opener = stack.pop()
            if opener is not None:
                raise ValueError(f"unbalanced term text: {text!r}")
            if tails and tails[-1] == len(stack):
                tails.pop()
                value = items.pop()
                for head in reversed(items):
                    value = Term("[|]", (head, value))
                outer.append(value)
            else:
                outer.append(items)
            items = outer
        elif first == "[":
            stack.append((items, None))
            items = []
        elif first == "'":
            if len(token) < 2:
                raise ValueError(f"cannot read term text: {text!r}")
            if token[-1] == "(":
                stack.append((items, _unescape(token[1:-2])))
                items = []
            else:
                body = token[1:-1]
                items.append(_unescape(body) if "\\" in body or "''" in body else body)
        elif first == ")":
            outer, name = stack.pop()
            if name is None:
                raise ValueError(f"unbalanced term text: {text!r}")
            outer.append(Term(name, tuple(items)))
            items = outer
        elif first.isdigit() or (first == "-" and _NUMBER.match(token)):
            items.append(_number(token))
        elif first == '"':
            if len(token) < 2:
                raise ValueError(f"cannot read term text: {text!r}")
            items.append(_unescape(token[1:-1]))
        elif first == "|":
            tails.append(len(stack) - 1)
        elif first in "()'\"" or "{" in token and token != "{}" and token != "{}(":
            raise ValueError(f"cannot read term text: {text!r}")
        elif token[-1] == "(":
            stack.append((items, token[:-1]))
            items = []
        elif first == "_":
            items.append(Var(token))
        else:
            # another atom (unicode letters, symbol chars: - =.. \\+ → ; ! {}), or a
            # blob such as <stream>(0x...) as its text
            items.append(token)
    if stack or len(items) != 1:
        raise ValueError(f"unbalanced term text: {text!r}")
    return items[0]
