"""Read the PlDoc ``%!`` comments of a Prolog source file (no Prolog needed).

A PlDoc comment is a block of ``%`` lines whose first line starts with ``%!``::

    %!  available(?Tool) is nondet.
    %
    %   True when Tool is in working condition and in its place.

The mode lines (``%!``) give name and arity; the summary is the first line of text
after them,
up to the end of its first sentence.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

_MODE = re.compile(r"^%!\s*(?P<text>.*\S)\s*$")
_COMMENT = re.compile(r"^%\s?(?P<text>.*)$")
_HEAD = re.compile(r"^(?P<name>[a-z][A-Za-z0-9_]*|'[^']*')\s*(?P<rest>.*)$")


@dataclass(frozen=True)
class DocComment:
    """The PlDoc of one predicate: its mode line and the first line of its description."""

    name: str
    arity: int
    mode: str
    summary: str


def _arity(args: str) -> int:
    """Count the top-level arguments of ``(a, b(c, d), e)``; 0 for no parentheses."""
    if not args.startswith("("):
        return 0
    depth, count = 0, 1
    for char in args:
        if char in "([{":
            depth += 1
        elif char in ")]}":
            depth -= 1
            if depth == 0:
                break
        elif char == "," and depth == 1:
            count += 1
    return count


def _first_sentence(text: str) -> str:
    """The text up to its first full stop that ends a sentence (not "e.g. the")."""
    match = re.search(r"(?<!e\.g)(?<!i\.e)\.(?=\s+[A-Z]|\s*$)", text)
    return text[: match.start() + 1] if match else text


def _parse_mode(mode: str) -> tuple[str, int] | None:
    match = _HEAD.match(mode)
    if not match:
        return None
    return match.group("name").strip("'"), _arity(match.group("rest"))


def doc_comments(path: Path) -> dict[tuple[str, int], DocComment]:
    """Map (name, arity) to the PlDoc comment of each documented predicate of `path`."""
    lines = path.read_text(encoding="utf-8").splitlines()
    docs: dict[tuple[str, int], DocComment] = {}
    i = 0
    while i < len(lines):
        modes: list[str] = []
        while i < len(lines) and (m := _MODE.match(lines[i].strip())):
            modes.append(m.group("text"))
            i += 1
        if not modes:
            i += 1
            continue
        paragraph: list[str] = []
        while i < len(lines) and (c := _COMMENT.match(lines[i].strip())):
            text = c.group("text").strip()
            if text and not text.startswith("@"):
                paragraph.append(text)
            elif paragraph:
                break
            i += 1
        while i < len(lines) and _COMMENT.match(lines[i].strip()):
            i += 1
        summary = _first_sentence(" ".join(paragraph))
        for mode in modes:
            parsed = _parse_mode(mode)
            if parsed and parsed not in docs:
                docs[parsed] = DocComment(parsed[0], parsed[1], mode, summary)
    return docs
