"""JSON values as types: what ``json.dumps`` writes, for the records ITA keeps.

    def to_dict(self) -> JsonObject:
        return {"arm": self.arm, "steps": [s.text for s in self.steps], "holding": None}

Sequences and mappings are the read-only kinds, so a ``list[str]`` or a
``dict[str, float]`` is a JSON value as it is (lists and dicts are invariant).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TypeAlias, Union

__all__ = ["JsonObject", "JsonValue"]

#: a value ``json.dumps`` writes: null, a boolean, a number, a string, an array, an object
JsonValue: TypeAlias = Union[None, bool, int, float, str, Sequence["JsonValue"], Mapping[str, "JsonValue"]]
#: a JSON object as a dict (what the ``to_dict`` methods return)
JsonObject: TypeAlias = dict[str, JsonValue]
