"""Value types of measurement specifications.

Units: the part frame is in millimetres (as the part's drawing and mesh are); `point` is
a location on the part's surface in that frame, `normal` the outward unit surface normal
there.  `nominal`, `lower` and `upper` are millimetres; `lower` and `upper` are signed
deviations from nominal (thickness 2.5 -0.127/+0.127; true position 0 -0/+0.5).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum

Vec3 = tuple[float, float, float]


class Tool(str, Enum):
    """Tool classes (the physical tools are instances in the workcell and kb/world.pl).

    Two shapes of ultrasonic probe: ``us_tool`` (the cell's probe, its tip axis 45 degrees
    off the flange axis) and ``us_bent`` (bent 90 degrees: its shaft across the flange axis,
    for walls the first cannot touch without the arm meeting the part); both are contact
    probes on the one gauge (:attr:`ultrasonic`), kb/world.pl's subtype/2 says the same.
    """

    ULTRASONIC = "us_tool"
    ULTRASONIC_BENT = "us_bent"
    SLRA = "slra_tool"

    @property
    def ultrasonic(self) -> bool:
        """Whether tools of this class are ultrasonic contact probes (on the gauge)."""
        return self is not Tool.SLRA

    @property
    def family(self) -> "Tool":
        """The class this one is a kind of: ``us_tool`` for every ultrasonic probe."""
        return Tool.ULTRASONIC if self.ultrasonic else self


def is_ultrasonic(tool_class: "Tool | str | None") -> bool:
    """Whether a tool class (or its spelling) is an ultrasonic contact probe's; False for
    None or a spelling that is no class."""
    try:
        return tool_class is not None and Tool(tool_class).ultrasonic
    except ValueError:
        return False


class MeasurementKind(str, Enum):
    """What a measurement measures.  The value is the spelling used in files and Prolog."""

    WEB_THICKNESS = "web_thickness"
    FLANGE_THICKNESS = "flange_thickness"
    HOLE_DIAMETER = "hole_diameter"
    HOLE_POSITION = "hole_position"
    FLANGE_HEIGHT = "flange_height"
    FLANGE_WIDTH = "flange_width"
    STIFFENER_HEIGHT = "stiffener_height"
    STIFFENER_WIDTH = "stiffener_width"
    EDGE_DISTANCE = "edge_distance"

    @classmethod
    def parse(cls, text: str) -> "MeasurementKind":
        """Parse a kind name; raises ValueError listing the valid names."""
        try:
            return cls(text.strip())
        except ValueError:
            valid = ", ".join(k.value for k in cls)
            raise ValueError(f"unknown kind {text.strip()!r} (valid: {valid})") from None


KIND_DESCRIPTIONS: dict[MeasurementKind, str] = {
    MeasurementKind.WEB_THICKNESS: "thickness of the web at a point (along the normal)",
    MeasurementKind.FLANGE_THICKNESS: "thickness of a flange wall at a point (along the normal)",
    MeasurementKind.HOLE_DIAMETER: "diameter of a hole; point = centre on the entry face, normal = hole axis",
    MeasurementKind.HOLE_POSITION: "true position of a hole axis relative to the datums, as a diameter",
    MeasurementKind.FLANGE_HEIGHT: "height of a flange above the web face",
    MeasurementKind.FLANGE_WIDTH: "width of a flange cap, across `direction`",
    MeasurementKind.STIFFENER_HEIGHT: "height of a stiffener above the web face",
    MeasurementKind.STIFFENER_WIDTH: "width of a stiffener, across `direction`",
    MeasurementKind.EDGE_DISTANCE: "distance from a hole centre to the nearest edge, along `direction`",
}


@dataclass(frozen=True)
class MeasurementSpec:
    """One dimensional measurement to perform on the part.

    id: unique name (letters, digits, '_', '-', '.'); kind: what is measured; feature: the
    id of the part feature it belongs to; point/normal: location on the part (mm, part
    frame) and outward unit normal; nominal/lower/upper: value and signed tolerance (mm);
    datum: datum reference frame (e.g. "A", "A|B|C"); direction: in-plane measuring
    direction for widths and edge distances (unit vector), None for other kinds.
    """

    id: str
    kind: MeasurementKind
    feature: str
    point: Vec3
    normal: Vec3
    nominal: float
    lower: float
    upper: float
    datum: str = "A"
    direction: Vec3 | None = None
    note: str = field(default="", compare=False)

    @property
    def low_limit(self) -> float:
        """Lowest conforming value (nominal + lower)."""
        return self.nominal + self.lower

    @property
    def high_limit(self) -> float:
        """Highest conforming value (nominal + upper)."""
        return self.nominal + self.upper

    @property
    def tolerance_band(self) -> float:
        """Width of the tolerance zone (upper - lower), mm."""
        return self.upper - self.lower


def unit(v: Vec3) -> Vec3:
    """Return `v` scaled to unit length; raises ValueError for a (near) zero vector."""
    n = math.sqrt(sum(c * c for c in v))
    if n < 1e-9:
        raise ValueError("zero-length vector")
    return (v[0] / n, v[1] / n, v[2] / n)
