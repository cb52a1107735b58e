"""Checks of measurement specs against the part they belong to.

The file-level checks (kinds, numbers, tolerances, duplicate ids) happen while reading
(`ita.specs.io`); this module checks what needs the part's mesh: every spec point must lie
on the part's surface within a stated distance.  The point of a hole measurement is the
hole's centre on its entry face, so it may lie up to the hole's radius (taken from the
feature's hole_diameter spec) plus that distance from the surface.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ita.errors import Location
from ita.specs.model import MeasurementKind, MeasurementSpec

HOLE_KINDS = frozenset({
    MeasurementKind.HOLE_DIAMETER, MeasurementKind.HOLE_POSITION, MeasurementKind.EDGE_DISTANCE,
})
DEFAULT_MAX_DISTANCE_MM = 0.5
#: points sent to one nearest-point query: bounds the memory of validating a big file
CHUNK_POINTS = 4096
#: problems listed one by one; the rest are counted in one closing line
MAX_PROBLEMS = 1000


def allowed_distances(specs: Sequence[MeasurementSpec], max_distance: float) -> np.ndarray:
    """(n,) float: how far each spec point may lie from the surface, mm."""
    radius_of: dict[str, float] = {}
    for s in specs:
        if s.kind is MeasurementKind.HOLE_DIAMETER:
            radius_of[s.feature] = max(radius_of.get(s.feature, 0.0), s.high_limit / 2.0)
    out = np.full(len(specs), max_distance, dtype=float)
    for i, s in enumerate(specs):
        if s.kind in HOLE_KINDS:
            out[i] += radius_of.get(s.feature, 0.0)
    return out


def surface_distances(mesh, points: np.ndarray, chunk: int = CHUNK_POINTS) -> np.ndarray:
    """(n,) float: distance of each (n,3) point (mm, part frame) to the mesh surface.

    The points go to the nearest-point query `chunk` at a time, so memory stays bounded
    however many there are (one query over a million points needs tens of GB)."""
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    out = np.zeros(len(points))
    for start in range(0, len(points), chunk):
        _, distance, _ = mesh.nearest.on_surface(points[start:start + chunk])
        out[start:start + chunk] = np.asarray(distance, dtype=float)
    return out


def _units_hint(points: np.ndarray, extents: np.ndarray) -> str:
    """When most points are off the part: whether their spread says the specs and the mesh
    are in different units (inches, metres), as a sentence; "" otherwise."""
    spread = float(np.max(np.ptp(points, axis=0)))
    size = float(np.max(extents))
    if spread <= 0 or size <= 0:
        return ""
    ratio = spread / size          # the points span at most the part: about the unit factor or less
    for low, high, what in ((8.0, 30.0, "the specs in millimetres and the mesh in inches"),
                            (300.0, 1100.0, "the specs in millimetres and the mesh in metres"),
                            (1 / 30.0, 1 / 20.0, "the specs in inches and the mesh in millimetres"),
                            (1 / 1100.0, 1 / 800.0, "the specs in metres and the mesh in millimetres")):
        if low <= ratio <= high:
            return (f"most points are off the part and they spread {ratio:.3g} times as far as the mesh: "
                    f"{what}? Both must be in millimetres")
    return ""


def check_on_surface(
    specs: Sequence[MeasurementSpec],
    mesh,
    file: str,
    lines: Sequence[int] | None = None,
    max_distance: float = DEFAULT_MAX_DISTANCE_MM,
    context: Sequence[MeasurementSpec] = (),
) -> list[tuple[Location, str]]:
    """Problems for specs whose point is farther than allowed from the mesh surface.

    `context` adds specs (e.g. the rest of the file) used to find hole radii.
    """
    if not specs:
        return []
    points = np.array([s.point for s in specs], dtype=float)
    dist = surface_distances(mesh, points)
    allowed = allowed_distances(list(specs) + list(context), max_distance)[: len(specs)]
    problems = []
    far = np.flatnonzero(dist > allowed)
    for i in far[:MAX_PROBLEMS]:
        line = lines[i] if lines is not None else 0
        s = specs[i]
        problems.append((
            Location(file, line, field="x"),
            f"point of {s.id} is {dist[i]:.3f} mm from the part's surface "
            f"(at most {allowed[i]:.3f} mm allowed)",
        ))
    if len(far) > MAX_PROBLEMS:
        problems.append((Location(file), f"... and {len(far) - MAX_PROBLEMS} more points off the surface"))
    if len(far) > len(specs) // 2 and len(specs) >= 3:
        hint = _units_hint(points, np.asarray(mesh.extents, dtype=float))
        if hint:
            problems.append((Location(file), hint))
    return problems
