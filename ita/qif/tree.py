"""QIF 3 XML as lxml trees: the namespace, element building, numbers as QIF writes them,
and the few reading helpers the importer shares.

Numbers: QIF's values are ``xs:decimal`` (no exponent), so :func:`decimal` writes the
shortest text that reads back to the same double, spelled out without an exponent.
Vectors and points are three such numbers separated by spaces.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from decimal import Decimal
from typing import Any

from lxml import etree

NS = "http://qifstandards.org/xsd/qif3"
XSI = "http://www.w3.org/2001/XMLSchema-instance"
#: QIF versions by namespace, for telling a QIF of another version from a file that is no QIF
OTHER_VERSIONS = {"http://qifstandards.org/xsd/qif2": "2", "http://qifstandards.org/xsd/qif1": "1"}
VERSION = "3.0.0"
#: QIF as the default namespace (the schema instance's prefix for the root's schemaLocation)
NSMAP = {None: NS, "xsi": XSI}

Element = Any  # an lxml element (lxml ships no type information)


def q(name: str) -> str:
    """The qualified tag of QIF element `name`: ``{namespace}name``."""
    return f"{{{NS}}}{name}"


def local(element: Element) -> str:
    """The tag of `element` without its namespace ('' for comments and processing
    instructions)."""
    tag = element.tag
    if not isinstance(tag, str):
        return ""
    return tag.rpartition("}")[2]


def decimal(x: float) -> str:
    """`x` as an xs:decimal: the shortest text that reads back to the same double, with no
    exponent (1e-05 -> 0.00001).  ValueError for NaN and the infinities."""
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"not a finite number: {x!r}")
    if x == 0:
        return "0"
    text = repr(x)
    if "e" in text or "E" in text:
        text = format(Decimal(text), "f")
    return text.removesuffix(".0")


def triple(v: Iterable[float]) -> str:
    """Three numbers as QIF writes a point or a vector: ``x y z``."""
    values = [float(c) for c in v]
    if len(values) != 3:
        raise ValueError(f"a point or vector has three numbers, got {len(values)}")
    return " ".join(decimal(c) for c in values)


def el(name: str, /, *children: Element | str | None, **attrs: str) -> Element:
    """A QIF element: children are elements (None skipped) or its text (one str)."""
    node = etree.Element(q(name), {k: v for k, v in attrs.items()}, nsmap=NSMAP)
    for child in children:
        if child is None:
            continue
        if isinstance(child, str):
            node.text = child
        else:
            node.append(child)
    return node


def listing(name: str, children: Iterable[Element], /, **attrs: str) -> Element:
    """A QIF list element with its required count: ``<Name n="k">...</Name>``."""
    items = list(children)
    node = el(name, n=str(len(items)), **attrs)
    node.extend(items)
    return node


def ids(name: str, refs: Iterable[int]) -> Element:
    """A list of references: ``<Name n="k"><Id>..</Id>...</Name>``."""
    return listing(name, (el("Id", str(r)) for r in refs))


def kids(element: Element, name: str | None = None) -> Iterator[Element]:
    """The child elements of `element` (of QIF name `name` when given), comments skipped."""
    for child in element:
        if isinstance(child.tag, str) and (name is None or local(child) == name):
            yield child


def kid(element: Element | None, *path: str) -> Element | None:
    """The first child element along `path` of QIF names, None when any step is missing."""
    node = element
    for name in path:
        if node is None:
            return None
        node = next(kids(node, name), None)
    return node


def text(element: Element | None, *path: str) -> str | None:
    """The stripped text of the element along `path` (None when it is missing)."""
    node = kid(element, *path)
    if node is None or node.text is None:
        return None
    return node.text.strip()


def to_bytes(root: Element) -> bytes:
    """The document as UTF-8 bytes with an XML declaration, indented two spaces."""
    etree.indent(root, space="  ")
    data: bytes = etree.tostring(root, xml_declaration=True, encoding="UTF-8")
    return data + b"\n"
