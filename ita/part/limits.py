"""The ranges of the bulkhead generator's parameters, and the constraints between them.

Every numeric field of bulkhead/part.toml has a range here, by its table's class in
ita.part.params (mm unless said otherwise), written beside the field in part.toml as
`range LO .. HI` (a test holds the two together).  Together with the constraints between fields (an opening and its flange
inside the outline's flange, a hole on its cap, ribs inside the outline and apart, a
bounded number of fastener holes and pockets of bounded size) they are checked when the
file is read, before anything is generated, so a file that would allocate terabytes or run
for minutes is refused at once, naming the field and its range.

The bounds keep a generation within seconds and a few hundred megabytes: a pocket's
placement grid (5 mm) is measured against its outline point by point, so the largest
pocket between ribs is bounded (MAX_POCKET_MM2), and so are the fastener holes per flange
(MAX_FASTENERS) and the ribs per direction (MAX_RIBS).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from ita.errors import Location
from ita.part.geometry2d import RoundedRect
from ita.seeds import SEED_MAX, SEED_MIN

if TYPE_CHECKING:
    from ita.part.params import BulkheadParams, Flange

MAX_RIBS = 30               # stiffeners.x and stiffeners.y: ribs per direction
MAX_FASTENERS = 1000        # fastener holes per flange (segments x holes per segment)
MAX_POCKET_MM2 = 1.0e6      # the largest pocket's box between ribs (and the outline), mm^2


@dataclass(frozen=True)
class Bound:
    """The range of a numeric parameter: lo .. hi, both included unless `open_low`
    (then lo itself is excluded: "> lo")."""

    lo: float
    hi: float
    open_low: bool = False

    def holds(self, value: float) -> bool:
        """Whether `value` lies in the range (NaN never does)."""
        above = value > self.lo if self.open_low else value >= self.lo
        return bool(above and value <= self.hi)

    def __str__(self) -> str:
        return f"{'> ' if self.open_low else ''}{_number(self.lo)} .. {_number(self.hi)}"


def _number(x: float) -> str:
    """A bound as written in part.toml: whole numbers in full (a seed's 9223372036854775807)."""
    return str(int(x)) if float(x).is_integer() else f"{x:g}"


#: parameter class (ita.part.params: a TOML table's type) -> field -> range; a list's
#: range is that of each of its numbers.  [outline] and [opening] share Outline's,
#: the two flanges Flange's.
RANGES: dict[str, dict[str, Bound]] = {
    "PartInfo": {"seed": Bound(SEED_MIN, SEED_MAX)},
    "Outline": {"width": Bound(10.0, 5000.0), "height": Bound(10.0, 5000.0),
                "corner_radius": Bound(0.0, 2500.0, True)},
    "Web": {"thickness": Bound(0.5, 50.0)},
    "Flange": {"height": Bound(1.0, 500.0), "wall_thickness": Bound(0.5, 50.0), "cap_width": Bound(1.0, 500.0),
               "cap_thickness": Bound(0.5, 50.0), "segments": Bound(1, 200), "fastener_pitch": Bound(5.0, 5000.0),
               "fastener_diameter": Bound(0.5, 50.0)},
    "Stiffeners": {"width": Bound(0.5, 50.0), "height": Bound(1.0, 500.0), "x": Bound(-2500.0, 2500.0),
                   "y": Bound(-2500.0, 2500.0)},
    "Holes": {"tooling_diameter": Bound(1.0, 100.0), "lightening_min_diameter": Bound(1.0, 2000.0),
              "lightening_max_diameter": Bound(1.0, 2000.0), "lightening_margin": Bound(0.0, 500.0),
              "lightening_fraction": Bound(0.0, 1.0)},
    "SpecParams": {"web_thickness_points": Bound(0, 5000), "web_point_margin": Bound(0.0, 500.0),
                   "stiffener_long_span": Bound(1.0, 10000.0)},
    "Tolerance": {k: Bound(0.0, 10.0, True) for k in (
        "thickness", "fastener_diameter", "tooling_diameter", "lightening_diameter", "true_position",
        "lightening_true_position", "height", "general")},
    "TruthParams": {"spread": Bound(0.0, 1.0), "out_of_tolerance": Bound(0.0, 1.0)},
}

#: list fields (class.field) and how many numbers each may hold
MAX_ITEMS = {"Stiffeners.x": MAX_RIBS, "Stiffeners.y": MAX_RIBS}

Problems = list[tuple[Location, str]]


def range_problem(kind: str, key: str, value: Any) -> str:
    """Why `value` of field `key` of parameter class `kind` is out of its range ("" when
    it is in)."""
    bound = RANGES.get(kind, {}).get(key)
    if bound is None:
        return ""
    if isinstance(value, tuple):
        most = MAX_ITEMS.get(f"{kind}.{key}")
        if most is not None and len(value) > most:
            return f"{len(value)} numbers; at most {most}"
        bad = [v for v in value if not bound.holds(v)]
        return f"each must lie in range {bound}, got {bad[0]!r}" if bad else ""
    return "" if bound.holds(value) else f"must lie in range {bound}, got {value!r}"


def cross_problems(p: BulkheadParams, file: str) -> Problems:
    """The constraints between fields that `p` (each field already in range) breaks."""
    problems: Problems = []

    def say(field: str, message: str) -> None:
        problems.append((Location(file, field=field), message))

    for name in ("outline", "opening"):
        o = getattr(p, name)
        if o.corner_radius > min(o.width, o.height) / 2:
            say(f"{name}.corner_radius", f"{o.corner_radius:g} is more than half the {name}'s width or height "
                                         f"({min(o.width, o.height) / 2:g})")
    for axis in ("width", "height"):
        inside = getattr(p.outline, axis) / 2 - p.outer_flange.cap_width
        opening = getattr(p.opening, axis) / 2 + p.inner_flange.cap_width
        if opening >= inside:
            say(f"opening.{axis}", f"the opening and its flange reach {opening:g} from the centre "
                                   f"(opening.{axis} / 2 + inner_flange.cap_width); they must stay inside the "
                                   f"outline's flange, {inside:g} (outline.{axis} / 2 - outer_flange.cap_width)")
    for name in ("outer_flange", "inner_flange"):
        _flange_problems(name, getattr(p, name), p, say)
    st = p.stiffeners
    if st.height <= p.web.thickness:
        say("stiffeners.height", f"{st.height:g} must be more than web.thickness ({p.web.thickness:g})")
    for axis, coords, half in (("x", st.x, p.outline.width / 2), ("y", st.y, p.outline.height / 2)):
        outside = [c for c in coords if abs(c) >= half]
        if outside:
            say(f"stiffeners.{axis}", f"a rib at {outside[0]:g} lies outside the outline (|{axis}| < {half:g})")
        ordered = sorted(coords)
        close = [(a, b) for a, b in zip(ordered, ordered[1:]) if b - a <= st.width]
        if close:
            say(f"stiffeners.{axis}", f"ribs at {close[0][0]:g} and {close[0][1]:g} are not apart by more than "
                                      f"stiffeners.width ({st.width:g})")
    if problems:
        return problems
    span_x = _largest_gap(st.x, p.outline.width / 2)
    span_y = _largest_gap(st.y, p.outline.height / 2)
    if span_x * span_y > MAX_POCKET_MM2:
        say("stiffeners", f"the largest pocket between ribs spans {span_x:g} x {span_y:g} mm "
                          f"({span_x * span_y:,.0f} mm^2); at most {MAX_POCKET_MM2:,.0f} mm^2: add ribs "
                          f"(stiffeners.x, stiffeners.y)")
    if p.holes.lightening_max_diameter < p.holes.lightening_min_diameter:
        say("holes.lightening_max_diameter", f"{p.holes.lightening_max_diameter:g} is less than "
                                             f"holes.lightening_min_diameter ({p.holes.lightening_min_diameter:g})")
    return problems


def _flange_problems(name: str, f: Flange, p: BulkheadParams, say: Any) -> None:
    """The constraints of one flange: its cap beyond its wall, above the web, a hole on the
    cap, and a bounded number of fastener holes along its contour."""
    if f.cap_width <= f.wall_thickness:
        say(f"{name}.cap_width", f"{f.cap_width:g} must be more than {name}.wall_thickness ({f.wall_thickness:g})")
    elif f.fastener_diameter >= f.cap_width - f.wall_thickness:
        say(f"{name}.fastener_diameter", f"{f.fastener_diameter:g} does not fit on the cap beyond the wall "
                                         f"({name}.cap_width - {name}.wall_thickness = "
                                         f"{f.cap_width - f.wall_thickness:g})")
    if f.height <= p.web.thickness + f.cap_thickness:
        say(f"{name}.height", f"{f.height:g} must be more than web.thickness + {name}.cap_thickness "
                              f"({p.web.thickness + f.cap_thickness:g})")
    o = p.outline if name == "outer_flange" else p.opening
    if o.corner_radius > min(o.width, o.height) / 2:
        return  # said already
    length = RoundedRect(o.width / 2, o.height / 2, o.corner_radius).length
    holes = f.segments * max(1, round(length / f.segments / f.fastener_pitch))
    if holes > MAX_FASTENERS:
        say(f"{name}.fastener_pitch", f"{f.fastener_pitch:g} mm along {length:,.0f} mm in {f.segments} segments "
                                      f"makes {holes:,} fastener holes; at most {MAX_FASTENERS:,} a flange")


def _largest_gap(coords: tuple[float, ...], half: float) -> float:
    """The widest span between neighbouring ribs (and the outline's sides) along one axis."""
    walls = [-half, *sorted(coords), half]
    return max(b - a for a, b in zip(walls, walls[1:]))
