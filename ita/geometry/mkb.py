"""The Measurement Knowledge Base (MKB): where the arm stands for each measurement.

One :class:`MkbEntry` per measurement spec, made by the Geometric Reasoner
(:mod:`ita.geometry.reasoner`):

- every measurement: the tool, the TCP pose (4, 4, world, m) and the joint configuration
  (6,) rad that takes it;
- the ultrasonic probe: the in-contact pose (the tip pressed `press_m` into the surface)
  and the approach point in free space `approach_distance` off the surface along the
  normal, each with its configuration;
- the SLRA: the viewing pose and the scan window (`fov_deg`, pixels), and the view group
  it belongs to: measurements that ONE range frame taken from one pose serves
  (:class:`ViewGroup`: its members, its anchor whose pose the frame is taken from).

Each spec has the entry of the tool the Sequence Planner chose for it when the MKB was
made (``entries``) and, where the tool rules allow another tool type for its kind (a
rib's width: the SLRA, or the probe on its side wall), an entry for that type too
(``alternatives``), so that a resequencing that moves it to the other type mid-run finds
where the arm must stand.  :meth:`MeasurementKB.entry_for` picks by tool class.

A measurement the reasoner could not place has ``status`` other than ``ok`` and a
reason, and no numbers.  The whole MKB is stored as one JSON file (atomic write) under
``ita_home()/mkb/<part>.json``, keyed by a digest of the specs and the workcell: a
stored MKB whose digest differs is stale.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ita.files.atomic import store_name, write_json_atomic
from ita.paths import ita_home

FloatArray = NDArray[np.float64]
MKB_VERSION = 4
OK = "ok"
#: the verdict of ``placed/2`` (kb/tools.pl) for a tool class the MKB placed a measurement for
PLACED = "placed"

__all__ = [
    "MKB_VERSION",
    "PLACED",
    "MeasurementKB",
    "MkbEntry",
    "ViewGroup",
    "load_mkb",
    "mkb_path",
    "save_mkb",
]


def _array(value: Any, shape: tuple[int, ...]) -> FloatArray | None:
    if value is None:
        return None
    out = np.asarray(value, dtype=float).reshape(shape)
    out.setflags(write=False)
    return out


def _rack_configuration(tool: str, value: object) -> FloatArray:
    """A stored rack configuration (6,); ValueError when it is null (the MKB is damaged)."""
    out = _array(value, (6,))
    if out is None:
        raise ValueError(f"the MKB's rack configuration of {tool!r} is null")
    return out


@dataclass(frozen=True, eq=False)
class MkbEntry:
    """Where the arm stands for one measurement.

    status: ``ok`` or why not (``no_pose``, ``approach_blocked``, ``contact_blocked``...), reason: one line.
    q / pose: the measuring configuration (6,) and TCP pose (4, 4): in contact for the
    probe, the viewing pose for the SLRA.  q_approach / pose_approach: the free-space
    approach point (the viewing pose itself for the SLRA).  press_m: how far the probe's
    spring-loaded tip is pushed in at contact.  standoff_m, fov_deg, pixels: the SLRA's
    stand-off and scan window.  group: the SLRA view group's id (None for the probe).
    """

    spec_id: str
    tool: str
    tool_class: str
    status: str = OK
    reason: str = ""
    q: FloatArray | None = None
    pose: FloatArray | None = None
    q_approach: FloatArray | None = None
    pose_approach: FloatArray | None = None
    press_m: float = 0.0
    standoff_m: float = 0.0
    fov_deg: tuple[float, float] | None = None
    pixels: tuple[int, int] | None = None
    group: str | None = None

    @property
    def ok(self) -> bool:
        return self.status == OK

    def to_dict(self) -> dict[str, Any]:
        def arr(a: FloatArray | None) -> list | None:
            return None if a is None else np.round(a, 12).tolist()

        return {
            "spec_id": self.spec_id, "tool": self.tool, "tool_class": self.tool_class,
            "status": self.status, "reason": self.reason, "q": arr(self.q), "pose": arr(self.pose),
            "q_approach": arr(self.q_approach), "pose_approach": arr(self.pose_approach),
            "press_m": self.press_m, "standoff_m": self.standoff_m,
            "fov_deg": None if self.fov_deg is None else list(self.fov_deg),
            "pixels": None if self.pixels is None else list(self.pixels), "group": self.group,
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> MkbEntry:
        return cls(
            spec_id=str(d["spec_id"]), tool=str(d["tool"]), tool_class=str(d["tool_class"]),
            status=str(d["status"]), reason=str(d.get("reason", "")),
            q=_array(d.get("q"), (6,)), pose=_array(d.get("pose"), (4, 4)),
            q_approach=_array(d.get("q_approach"), (6,)), pose_approach=_array(d.get("pose_approach"), (4, 4)),
            press_m=float(d.get("press_m", 0.0)), standoff_m=float(d.get("standoff_m", 0.0)),
            fov_deg=None if d.get("fov_deg") is None else (float(d["fov_deg"][0]), float(d["fov_deg"][1])),
            pixels=None if d.get("pixels") is None else (int(d["pixels"][0]), int(d["pixels"][1])),
            group=d.get("group"),
        )


@dataclass(frozen=True)
class ViewGroup:
    """SLRA measurements served by one range frame: `members` (spec ids), the `anchor`
    member whose viewing pose the frame is taken from, and the shared window."""

    id: str
    anchor: str
    members: tuple[str, ...]
    fov_deg: tuple[float, float]
    pixels: tuple[int, int]

    def to_dict(self) -> dict[str, Any]:
        return {"id": self.id, "anchor": self.anchor, "members": list(self.members),
                "fov_deg": list(self.fov_deg), "pixels": list(self.pixels)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> ViewGroup:
        return cls(str(d["id"]), str(d["anchor"]), tuple(map(str, d["members"])),
                   (float(d["fov_deg"][0]), float(d["fov_deg"][1])), (int(d["pixels"][0]), int(d["pixels"][1])))


@dataclass(frozen=True, eq=False)
class MeasurementKB:
    """The MKB of one part: entries by spec id, SLRA view groups by id, the digest of
    the specs and workcell it was made for, and the rack configurations above each tool's
    slot (tool -> (6,)) where a tool change starts."""

    part: str
    digest: str
    entries: Mapping[str, MkbEntry]
    groups: Mapping[str, ViewGroup] = field(default_factory=dict)
    rack: Mapping[str, FloatArray] = field(default_factory=dict)
    build_seconds: float = 0.0
    version: int = MKB_VERSION
    alternatives: Mapping[str, tuple[MkbEntry, ...]] = field(default_factory=dict)

    def entry(self, spec_id: str) -> MkbEntry:
        """The entry of `spec_id`; KeyError when the MKB has none."""
        return self.entries[spec_id]

    def entry_for(self, spec_id: str, tool_class: str) -> MkbEntry | None:
        """The entry of `spec_id` for a tool of `tool_class` (``us_tool``, ``slra_tool``):
        its own entry when that is the class, else an alternative's; None when the MKB has
        none for that class."""
        e = self.entries.get(spec_id)
        if e is not None and e.tool_class == tool_class:
            return e
        return next((a for a in self.alternatives.get(spec_id, ()) if a.tool_class == tool_class), None)

    def group_of(self, spec_id: str) -> ViewGroup | None:
        """The view group of an SLRA measurement (None for the probe or an unplaced one)."""
        e = self.entries.get(spec_id)
        return None if e is None or e.group is None else self.groups.get(e.group)

    def problems(self) -> list[MkbEntry]:
        """The entries that could not be placed."""
        return [e for e in self.entries.values() if not e.ok]

    def placement(self) -> dict[str, tuple[tuple[str, str], ...]]:
        """Spec id -> ((tool class, verdict), ...) for every class the MKB tried to place the
        measurement for (its own entry, then the alternatives): verdict :data:`PLACED` or the
        entry's status (``contact_blocked``, ...).  The tool rules' ``placed/2`` facts."""
        out: dict[str, dict[str, str]] = {}
        for e in [*self.entries.values(), *(a for alts in self.alternatives.values() for a in alts)]:
            out.setdefault(e.spec_id, {}).setdefault(e.tool_class, PLACED if e.ok else e.status)
        return {k: tuple(v.items()) for k, v in out.items()}

    def counts(self) -> dict[str, int]:
        """Entries per status."""
        out: dict[str, int] = {}
        for e in self.entries.values():
            out[e.status] = out.get(e.status, 0) + 1
        return out

    def frames_needed(self, spec_ids: Iterable[str] | None = None) -> int:
        """How many SLRA frames the placed SLRA measurements (of `spec_ids`) need."""
        ids = set(self.entries) if spec_ids is None else set(spec_ids)
        return len({e.group for e in self.entries.values() if e.ok and e.group and e.spec_id in ids})

    def to_dict(self) -> dict[str, Any]:
        return {"version": self.version, "part": self.part, "digest": self.digest,
                "build_seconds": round(self.build_seconds, 3),
                "rack": {k: np.round(v, 12).tolist() for k, v in self.rack.items()},
                "groups": [g.to_dict() for g in self.groups.values()],
                "entries": [e.to_dict() for e in self.entries.values()],
                "alternatives": [a.to_dict() for alts in self.alternatives.values() for a in alts]}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> MeasurementKB:
        if d.get("version") != MKB_VERSION:
            raise ValueError(f"MKB version {d.get('version')!r}, expected {MKB_VERSION}")
        entries = {e["spec_id"]: MkbEntry.from_dict(e) for e in d["entries"]}
        groups = {g["id"]: ViewGroup.from_dict(g) for g in d["groups"]}
        rack = {k: _rack_configuration(k, v) for k, v in d.get("rack", {}).items()}
        alternatives: dict[str, tuple[MkbEntry, ...]] = {}
        for a in d.get("alternatives", []):
            e = MkbEntry.from_dict(a)
            alternatives[e.spec_id] = alternatives.get(e.spec_id, ()) + (e,)
        return cls(str(d["part"]), str(d["digest"]), entries, groups, rack, float(d.get("build_seconds", 0.0)),
                   alternatives=alternatives)


def mkb_path(part_name: str) -> Path:
    """Where the MKB of part `part_name` is stored: ``ita_home()/mkb/<part>.json``."""
    return ita_home() / "mkb" / f"{store_name(part_name)}.json"


def save_mkb(mkb: MeasurementKB, path: Path | None = None) -> Path:
    """Store `mkb` atomically (default :func:`mkb_path`); returns the path."""
    return write_json_atomic(path or mkb_path(mkb.part), mkb.to_dict())


def load_mkb(part_name: str, digest: str | None = None, path: Path | None = None) -> MeasurementKB | None:
    """The stored MKB of `part_name`, or None when there is none, it is unreadable, or
    (given `digest`) it was made for other specs or another workcell."""
    path = path or mkb_path(part_name)
    if not path.is_file():
        return None
    try:
        mkb = MeasurementKB.from_dict(json.loads(path.read_text(encoding="utf-8")))
    except (ValueError, KeyError, TypeError):
        return None
    if digest is not None and mkb.digest != digest:
        return None
    return mkb
