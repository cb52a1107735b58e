"""A part at a glance: size, features and specs counted by kind."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from typing import Any, Sequence

from ita.part.model import FeatureKind, Part
from ita.specs.model import MeasurementKind, MeasurementSpec


@dataclass(frozen=True)
class PartSummary:
    """Size (mm, extent along X, Y, Z), mesh facts, features and specs by kind.

    unreachable: specs outside the arm's reach, None when not computed.
    """

    name: str
    directory: str
    size: tuple[float, float, float]
    triangles: int
    watertight: bool
    features: tuple[tuple[str, int], ...]
    specs: tuple[tuple[str, int], ...]
    unreachable: int | None = None

    @property
    def spec_count(self) -> int:
        """Number of specs."""
        return sum(n for _, n in self.specs)

    @property
    def feature_count(self) -> int:
        """Number of features."""
        return sum(n for _, n in self.features)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict."""
        return {
            "name": self.name, "directory": self.directory, "size_mm": list(self.size),
            "triangles": self.triangles, "watertight": self.watertight,
            "features": dict(self.features), "feature_count": self.feature_count,
            "specs": dict(self.specs), "spec_count": self.spec_count,
            "unreachable": self.unreachable,
        }


def summarize(part: Part, specs: Sequence[MeasurementSpec], unreachable: int | None = None) -> PartSummary:
    """The summary of `part` with its `specs` (every kind listed, zero counts included)."""
    lo, hi = part.mesh.bounds
    sx, sy, sz = (round(float(v), 3) for v in hi - lo)
    fk = Counter(f.kind for f in part.features)
    sk = Counter(s.kind for s in specs)
    return PartSummary(
        name=part.name, directory=str(part.directory),
        size=(sx, sy, sz),
        triangles=int(len(part.mesh.faces)), watertight=bool(part.mesh.is_watertight),
        features=tuple((k.value, fk.get(k, 0)) for k in FeatureKind),
        specs=tuple((k.value, sk.get(k, 0)) for k in MeasurementKind),
        unreachable=unreachable,
    )
