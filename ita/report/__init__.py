"""Reports of a run: the per-feature results, the part's verdict, charts, HTML and PDF.

    text = build_report(archive, run_id, specs=specs, true_values=None)      # HTML page
    pdf = build_pdf(archive, run_id, specs=specs)                            # PDF bytes
    write_report(path, text_or_bytes)

Modules: :mod:`~ita.report.data` (values read from the archive: summary, verdict, the
table's rows), :mod:`~ita.report.sections` (the report as sections of JSON the pages
draw), :mod:`~ita.report.figures` (interactive plotly.js figures), :mod:`~ita.report.charts`
(static matplotlib charts), :mod:`~ita.report.result` (one result opened),
:mod:`~ita.report.scene` (the part and workcell in 3-D), :mod:`~ita.report.page` (the
self-contained HTML), :mod:`~ita.report.pdf` (the printable PDF), :mod:`~ita.report.assets`
(the scripts, all shipped with the package).  This package never reads true values
itself: the caller passes them (`ita.scoring`), for simulated runs only.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from ita.archive.store import Archive
from ita.errors import InputError, Location
from ita.files.atomic import write_atomic
from ita.report.data import (
    GOAL_HOURS,
    MANUAL_HOURS,
    ReportData,
    Summary,
    Verdict,
    collect,
    summarize,
)
from ita.report.page import html_page
from ita.report.pdf import pdf_report
from ita.report.result import result_payload
from ita.report.sections import report_payload

__all__ = ["FORMATS", "GOAL_HOURS", "MANUAL_HOURS", "ReportData", "Summary", "Verdict", "build_pdf",
           "build_report", "collect", "report_format", "summarize", "write_report"]

#: file extensions a report can be written as
FORMATS = {".html": "html", ".htm": "html", ".pdf": "pdf"}
#: results not proven to conform whose drill-down (range image, plan, ...) the HTML includes
DRILL_LIMIT = 40


def report_format(path: Path | str) -> str:
    """"html" or "pdf" from the file's extension; InputError for any other."""
    ext = Path(path).suffix.lower()
    if ext not in FORMATS:
        raise InputError([(Location(str(path), field="-o"), "a report is written as .html (one interactive page) "
                           f"or .pdf (printable), not {ext or 'a file without an extension'}")])
    return FORMATS[ext]


def build_report(archive: Archive, run_id: str, *, specs: Iterable[Any] | None = None,
                 true_values: Mapping[str, float] | None = None, scene: Any = None,
                 drill_limit: int = DRILL_LIMIT, injected: Any = None) -> str:
    """The self-contained HTML report of run `run_id` (scoring only with `true_values`);
    scene (ita.report.scene.PartScene): the part's mesh and workcell for the 3-D views."""
    data = collect(archive, run_id, specs if specs is not None else (scene.specs if scene else None))
    payload = report_payload(data, true_values=true_values, mesh=None if scene is None else scene.mesh,
                             injected=injected)
    failed = [r.spec_id for r in data.results if r.failed][:drill_limit]
    drill = {}
    for spec_id in failed:
        page = result_payload(archive, run_id, spec_id, scene=scene, max_pixels=160)
        if page is not None:
            drill[spec_id] = page
    return html_page(payload, drill)


def build_pdf(archive: Archive, run_id: str, *, specs: Iterable[Any] | None = None,
              true_values: Mapping[str, float] | None = None, scene: Any = None, injected: Any = None) -> bytes:
    """The printable PDF report of run `run_id` (the part's verdict on page 1)."""
    data = collect(archive, run_id, specs if specs is not None else (scene.specs if scene else None))
    payload = report_payload(data, true_values=true_values, injected=injected,
                             only=("summary", "results", "two_arms", "breakdown", "events", "exceptions", "scoring"))
    return pdf_report(data, payload, mesh=None if scene is None else scene.mesh)


def write_report(path: Path | str, content: str | bytes, make_dirs: bool = False) -> Path:
    """Write a report atomically (a temporary file renamed into place); returns the path.
    Refuses (InputError) an empty name, a path that exists and is not a regular file, and
    a missing directory unless `make_dirs` (ita.files.atomic)."""
    return write_atomic(path, content, what="-o", make_dirs=make_dirs)
