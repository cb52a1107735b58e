"""The series SPC charts: one design's characteristics over its serials, from the archive.

The runs of one part (its name) that carry a serial number are the serials; a serial
inspected more than once counts once, by its latest run that measured the most.  A
characteristic's series holds the serials where it was measured, in the order the serials
were first inspected (the production order, as far as the archive knows it).  Only
measured values enter: a result not done has no value to chart.

    serials, series = design_series(archive, "bulkhead", kind="hole_diameter")
"""

from __future__ import annotations

from dataclasses import dataclass

from ita.archive import Archive, Outcome
from ita.archive.model import BOUNDED_BELOW, RunInfo
from ita.spc.chart import Series

__all__ = ["SerialRun", "design_series"]


@dataclass(frozen=True)
class SerialRun:
    """A serial and the run whose results stand for it."""

    serial: str
    run_id: str
    created: str
    results: int


def _serial_runs(archive: Archive, part: str) -> list[SerialRun]:
    chosen: dict[str, tuple[RunInfo, str]] = {}
    first: dict[str, str] = {}
    for info in archive.runs():
        serial = info.settings.get("serial")
        if info.part != part or not isinstance(serial, str) or info.settings.get("task", "inspect_part") != \
                "inspect_part":
            continue
        first.setdefault(serial, info.created)
        old = chosen.get(serial)
        if old is None or (info.done, info.created) >= (old[0].done, old[0].created):
            chosen[serial] = (info, serial)
    runs = [SerialRun(serial, info.id, first[serial], info.done) for serial, (info, _) in chosen.items()]
    return sorted(runs, key=lambda r: (r.created, r.serial))


def design_series(archive: Archive, part: str, kind: str | None = None) -> tuple[list[SerialRun], list[Series]]:
    """The serials of `part` in the archive and a series per characteristic (of `kind`)."""
    runs = _serial_runs(archive, part)
    values: dict[str, list[tuple[str, float, float]]] = {}
    limits: dict[str, tuple[str, float | None, float]] = {}
    for r in runs:
        for res in archive.results(r.run_id):
            if res.outcome is not Outcome.MEASURED or res.value is None or (kind is not None and res.kind != kind):
                continue
            values.setdefault(res.spec_id, []).append((r.serial, float(res.value), float(res.u or 0.0)))
            low = None if res.kind in BOUNDED_BELOW else res.nominal + res.lower
            limits[res.spec_id] = (str(res.kind), low, res.nominal + res.upper)
    series = [Series(spec, limits[spec][0], limits[spec][1], limits[spec][2], tuple(s for s, _, _ in pts),
                     tuple(v for _, v, _ in pts), tuple(u for _, _, u in pts)) for spec, pts in values.items()]
    return runs, series
