"""AS9102 Rev C Form 3 (Characteristic Accountability) of a run, as an .xlsx workbook.

    content = form3_xlsx(archive, run_id)       # bytes of the workbook
    write_atomic(path, content, what="-o")

One row per result of the run, in the run's order: characteristic number (1..n),
reference location (the spec's x, y, z in mm, part frame), designator (spec id and
kind), requirement (nominal and tolerance), result (the value with U, or why there is
none), the tool that measured it, a nonconformance number for a result that does not
conform (``NC-<run id>-<n>``, n counting the nonconformances) or a note for an uncertain
one, and the decision.  Above the table, Form 1's fields: part number and name (the
run's part), serial number (the run's ``serial`` setting, else blank), FAIR number (the
run id), organization, date, and the part's verdict.  Cells are written as text or
numbers, never formulas (a spec id starting with ``=`` stays text).  The PDF report
has the same form as pages of its own (:func:`form3_header`, :func:`form3_rows`).
"""

from __future__ import annotations

import io
from typing import Any

from ita.archive.model import StoredResult
from ita.archive.store import Archive
from ita.report.data import ReportData, collect, result_row, summarize

__all__ = ["EXTENSION", "FORM3_COLUMNS", "ORGANIZATION", "TITLE", "designator", "form3_header", "form3_rows",
           "form3_xlsx",
           "requirement", "result_text", "tooling"]

EXTENSION = ".xlsx"
ORGANIZATION = "ITA (simulation)"
FORM3_COLUMNS = ("5. Char. No.", "6. Reference Location (x, y, z mm, part frame)", "7. Characteristic Designator",
                 "8. Requirement", "9. Results", "10. Designed / Qualified Tooling", "11. Nonconformance Number",
                 "Decision")
UNCERTAIN_NOTE = "uncertain (ISO 14253-1)"
TITLE = "AS9102 Rev C, Form 3: Characteristic Accountability, Verification and Compatibility Evaluation"


def requirement(row: dict[str, Any]) -> str:
    """``3.000 +0.127/-0.127 mm``: the nominal with its signed tolerance."""
    return f"{row['nominal']:.3f} {row['upper']:+.3f}/{row['lower']:+.3f} mm"


def designator(row: dict[str, Any]) -> str:
    kind = row.get("kind")
    return f"{row['spec_id']} ({str(kind).replace('_', ' ')})" if kind else str(row["spec_id"])


def result_text(row: dict[str, Any]) -> str:
    """The measured value with U, or ``not done: <reason>`` / ``cannot be done: <reason>``."""
    if row["value"] is not None:
        text = f"{row['value']:.4f} mm"
        if row["U"] is not None:
            text += f", U = {row['U']:.4f} mm (k = {row['k']:g})"
        return text
    label = str(row["outcome"]).replace("_", " ")
    reason = row.get("reason") or ""
    return f"{label}: {reason}" if reason and reason != label else label


def tooling(tool: str | None) -> str:
    """The tool that measured it, named for a reader: ``ITA ultrasonic probe us_probe_1``."""
    if not tool:
        return ""
    low = tool.lower()
    if "slra" in low or "laser" in low:
        return f"ITA laser range sensor {tool}"
    if low.startswith("us") or "ultrason" in low or "probe" in low:
        return f"ITA ultrasonic probe {tool}"
    return f"ITA tool {tool}"


def _location(row: dict[str, Any]) -> str:
    if row["x"] is None:
        return ""
    return f"{row['x']:.3f}, {row['y']:.3f}, {row['z']:.3f}"


def form3_rows(results: list[StoredResult] | tuple[StoredResult, ...], run_id: str) -> list[tuple[Any, ...]]:
    """The table's rows (FORM3_COLUMNS), one per result, in the order given."""
    rows = []
    nc = 0
    for n, r in enumerate(results, 1):
        row = result_row(r)
        decision = row["decision"]
        if decision == "does_not_conform":
            nc += 1
            ncr = f"NC-{run_id}-{nc}"
        elif decision == "uncertain":
            ncr = UNCERTAIN_NOTE
        else:
            ncr = ""
        rows.append((n, _location(row), designator(row), requirement(row), result_text(row), tooling(r.tool), ncr,
                     decision.replace("_", " ")))
    return rows


def form3_header(data: ReportData) -> list[tuple[str, Any]]:
    """Form 1's fields above the table: part number and name, serial, FAIR number,
    organization, date and the part's verdict."""
    summary = summarize(data)
    info = data.run
    serial = info.settings.get("serial")
    return [("1. Part Number", info.part), ("2. Part Name", info.part),
            ("3. Serial Number", "" if serial is None else str(serial)), ("4. FAIR Number", info.id),
            ("Organization Name", ORGANIZATION), ("Date", (info.ended or info.created or "")[:10]),
            ("Part verdict", f"{summary.verdict.value}: {summary.verdict_reason}")]


def _header(archive: Archive, run_id: str) -> tuple[list[tuple[str, Any]], list[tuple[Any, ...]]]:
    data = collect(archive, run_id)
    return form3_header(data), form3_rows(data.results, data.run.id)


def _text(value: Any) -> Any:
    """A cell's value: numbers as they are, text without the characters a workbook cannot hold."""
    if value is None or isinstance(value, (int, float)):
        return value
    from openpyxl.cell.cell import ILLEGAL_CHARACTERS_RE

    return ILLEGAL_CHARACTERS_RE.sub("", str(value))


def _put(ws: Any, row: int, column: int, value: Any) -> Any:
    cell = ws.cell(row=row, column=column, value=_text(value))
    if isinstance(cell.value, str):
        cell.data_type = "s"  # "=..." is text here, never a formula
    return cell


def form3_xlsx(archive: Archive, run_id: str) -> bytes:
    """The workbook (bytes) of run `run_id`'s Form 3, Form 1's fields above the table."""
    from openpyxl import Workbook
    from openpyxl.styles import Alignment, Font

    fields, rows = _header(archive, run_id)
    wb = Workbook()
    ws = wb.active
    ws.title = "Form 3"
    _put(ws, 1, 1, TITLE).font = Font(bold=True, size=12)
    for i, (label, value) in enumerate(fields, 2):
        _put(ws, i, 1, label).font = Font(bold=True)
        _put(ws, i, 2, value)
    top = len(fields) + 3
    for c, name in enumerate(FORM3_COLUMNS, 1):
        cell = _put(ws, top, c, name)
        cell.font = Font(bold=True)
        cell.alignment = Alignment(wrap_text=True, vertical="top")
    for i, values in enumerate(rows, top + 1):
        for c, value in enumerate(values, 1):
            _put(ws, i, c, value)
    for letter, width in zip("ABCDEFGH", (16, 30, 34, 24, 44, 34, 28, 18)):
        ws.column_dimensions[letter].width = width
    ws.freeze_panes = ws.cell(row=top + 1, column=1)
    buf = io.BytesIO()
    wb.save(buf)
    return buf.getvalue()
