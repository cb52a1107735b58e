"""Vision's context for a loaded part: what it knows of the part and its cell, and which
SLRA calibration stands for it.

    ctx = vision_context(part, workcell)            # specs read from the part
    ctx = vision_context(part, workcell, tool="slra_2", specs=specs)

The cell's calibration (``bulkhead/slra_calibration.json``, made on generated bulkheads
of other seeds) stands for generated bulkheads, the kind its reference workpieces were;
a user's part has its own, made on its master (`ita part calibrate`,
:mod:`ita.offline.master`), or none.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ita.part.model import Pocket
from ita.specs.io import read_specs
from ita.specs.model import MeasurementKind as K
from ita.specs.model import MeasurementSpec
from ita.vision.calibration import SlraCalibration
from ita.vision.context import MeshFloor, VisionContext

__all__ = ["like_the_references", "part_calibration_path", "vision_context"]


def vision_context(part: Any, workcell: Any, tool: str = "slra_1",
                   specs: Sequence[MeasurementSpec] | None = None) -> VisionContext:
    """Vision's context of a loaded Part in a Workcell (specs: default read from the
    part), with the SLRA calibration that stands for the part."""
    specs = read_specs(part.specs_path) if specs is None else specs
    t = workcell.tool(tool)
    web = [s.upper for s in specs if s.kind is K.WEB_THICKNESS]
    zones = {s.feature: s.upper for s in specs if s.kind is K.HOLE_POSITION}
    diameters = {s.feature: (s.upper - s.lower) / 2 for s in specs if s.kind is K.HOLE_DIAMETER}
    features = {f.id: f for f in part.features}
    floor = None if any(isinstance(f, Pocket) for f in features.values()) else MeshFloor(part.mesh)
    calibration = (SlraCalibration.load() if like_the_references(part) else
                   SlraCalibration.load(part_calibration_path(part.directory)))
    return VisionContext(features, workcell.part, t.standoff_nominal, tuple(t.fov_deg),
                         max(web) if web else 0.127, zones, workcell.arm.repeatability_m / 3,
                         diameter_tolerances=diameters, calibration=calibration, floor=floor)


def part_calibration_path(part_directory: Path | str) -> Path:
    """A user part's own SLRA calibration, made on its master (`ita part calibrate`)."""
    return Path(part_directory) / "slra_calibration.json"


def like_the_references(part: Any) -> bool:
    """Whether the part is of the kind the SLRA's calibration study measured: a bulkhead
    from the generator (part.json says so), not a user's own mesh."""
    return (getattr(part, "metadata", None) or {}).get("generator") == "ita.part.bulkhead"
