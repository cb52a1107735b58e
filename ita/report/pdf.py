"""The printable report: a PDF made with reportlab, no browser needed.

    data = pdf_report(report_data, payload, mesh=mesh)      # bytes of an A4 PDF

Page 1: the part's verdict, why, the key figures (results, cycle time and, for a whole
part, the comparison with the manual method and the 1987 goal; a partial run's rate and
its labelled extrapolation) and the counts by decision.  Then the results not proven to
conform, the part map, the Gantt chart, the run's events, every result, and, for a
simulated run with true values, the scoring in its own labelled section.  Charts are
matplotlib PNGs at 150 dpi.
"""

from __future__ import annotations

import io
from collections.abc import Mapping, Sequence
from typing import Any

from ita.report import as9102, charts
from ita.report.data import STATUS_COLOURS, ReportData

VERDICT_COLOURS = {"accept": "#2ca02c", "reject": "#d62728", "incomplete": "#e68a00"}
RESULT_HEADER = ("#", "spec", "kind", "tool", "nominal", "measured", "deviation", "tolerance", "U", "U/tol",
                 "decision", "reason")


def _fmt(x: Any, digits: int = 4) -> str:
    if x is None:
        return ""
    return f"{x:.{digits}f}" if isinstance(x, float) else str(x)


def _result_cells(r: Mapping[str, Any]) -> list[str]:
    return [str(r["seq"]), r["spec_id"], r["kind"] or "", r["tool"] or "", _fmt(r["nominal"]), _fmt(r["value"]),
            "" if r["deviation"] is None else f"{r['deviation']:+.4f}", f"{r['lower']:+.3f}/{r['upper']:+.3f}",
            _fmt(r["U"]), "" if r["U_over_tolerance"] is None else f"{100 * r['U_over_tolerance']:.0f} %",
            r["decision"].replace("_", " "), r["reason"] or ""]


def pdf_report(data: ReportData, payload: Mapping[str, Any], *, mesh: Any = None) -> bytes:
    """The PDF of the report whose sections are `payload` (ita.report.sections)."""
    from reportlab.lib import colors
    from reportlab.lib.pagesizes import A4, landscape
    from reportlab.lib.styles import ParagraphStyle, getSampleStyleSheet
    from reportlab.lib.units import mm
    from reportlab.platypus import (
        Image,
        LongTable,
        PageBreak,
        Paragraph,
        SimpleDocTemplate,
        Spacer,
        Table,
        TableStyle,
    )

    styles = getSampleStyleSheet()
    small = ParagraphStyle("small", parent=styles["BodyText"], fontSize=7, leading=8.5)
    body = styles["BodyText"]
    s = payload["summary"]
    sections = {sec["id"]: sec for sec in payload["sections"]}
    page_w, page_h = landscape(A4)
    width = page_w - 30 * mm
    story: list[Any] = []

    def esc(x: Any) -> str:
        return str("" if x is None else x).replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")

    def image(png: bytes | None, max_h: float) -> None:
        if not png:
            return
        img = Image(io.BytesIO(png))
        scale = min(width / img.imageWidth, max_h / img.imageHeight)
        img.drawWidth, img.drawHeight = img.imageWidth * scale, img.imageHeight * scale
        story.append(img)

    def grid(rows: Sequence[Sequence[Any]], header: bool = True, widths: Any = None, font: float = 8) -> Any:
        t = LongTable(rows, colWidths=widths, repeatRows=1 if header else 0)
        style = [("FONTSIZE", (0, 0), (-1, -1), font), ("GRID", (0, 0), (-1, -1), 0.25, colors.grey),
                 ("VALIGN", (0, 0), (-1, -1), "TOP"), ("LEFTPADDING", (0, 0), (-1, -1), 3),
                 ("RIGHTPADDING", (0, 0), (-1, -1), 3)]
        if header:
            style.append(("BACKGROUND", (0, 0), (-1, 0), colors.HexColor("#eeeeee")))
        t.setStyle(TableStyle(style))
        return t

    # ---- page 1: the verdict
    story.append(Paragraph(f"ITA inspection report: run {esc(payload['run'])}", styles["Title"]))
    verdict = Table([[f"PART {s['verdict'].upper()}"]], colWidths=[110 * mm], rowHeights=[16 * mm])
    verdict.setStyle(TableStyle([("BACKGROUND", (0, 0), (-1, -1), colors.HexColor(VERDICT_COLOURS[s["verdict"]])),
                                 ("TEXTCOLOR", (0, 0), (-1, -1), colors.white), ("FONTSIZE", (0, 0), (-1, -1), 24),
                                 ("FONTNAME", (0, 0), (-1, -1), "Helvetica-Bold"),
                                 ("ALIGN", (0, 0), (-1, -1), "CENTER"), ("VALIGN", (0, 0), (-1, -1), "MIDDLE")]))
    story += [verdict, Spacer(1, 3 * mm), Paragraph(f"<b>{esc(s['verdict_reason'])}</b>", body), Spacer(1, 3 * mm)]
    run = sections.get("summary", {}).get("run", {})
    figures = [("part", f"{run.get('part', '')}  ({run.get('part_dir') or 'built-in'})"),
               ("status", run.get("status", "")),
               ("measurements", (f"{s['done']} of {s['part_total']} specs of the part"
                                 if s.get("part_known", True) else
                                 f"{s['done']} of the {s['run_total']} the run set out to do (the part's specs "
                                 "are not at hand)")
                + ("" if s["run_total"] == s["part_total"] or not s.get("part_known", True)
                   else f" (the run set out to do {s['run_total']})")),
               ("simulated cycle time", f"{s['cycle_h']:.3f} h ({s['cycle_s']:.1f} s)")]
    if s["complete"]:
        figures += [(f"manual method ({s['manual_h']:g} h)", f"{s['speedup_manual']:.1f}x faster"),
                    (f"goal of 1987 ({s['goal_h']:g} h)", f"{s['ratio_goal']:.2f} of the goal time ("
                     + ("met" if s["ratio_goal"] <= 1 else "not met") + ")")]
    else:
        figures += [("rate", "-" if s["rate_s"] is None else f"{s['rate_s']:.1f} s simulated per measurement"),
                    ("whole part, extrapolated (not measured)",
                     "-" if s["projected_h"] is None else f"{s['projected_h']:.2f} h"),
                    ("manual method, 1987 goal", "compared only for a run of the whole part: not this one")]
    figures += [("run", run.get("id", "")), ("created / ended (UTC)", f"{run.get('created', '')} / {run.get('ended') or '-'}")]
    story.append(grid([[k, v] for k, v in figures], header=False, widths=[75 * mm, 150 * mm], font=10))
    story.append(Spacer(1, 4 * mm))
    counts = [["decision", "results"]] + [[k.replace("_", " "), str(n)] for k, n in s["counts"].items()]
    t = grid(counts, widths=[60 * mm, 30 * mm], font=10)
    t.setStyle(TableStyle([("TEXTCOLOR", (0, i + 1), (0, i + 1), colors.HexColor(STATUS_COLOURS[k]))
                           for i, k in enumerate(s["counts"])]))
    story.append(t)
    if s["missing_count"]:
        story.append(Paragraph(f"{s['missing_count']} spec(s) of the part have no result.", body))
    summary = sections.get("summary", {})
    if summary.get("settings"):
        story += [Spacer(1, 3 * mm), Paragraph("Run settings", styles["Heading3"]),
                  grid([[k, Paragraph(esc(v), small)] for k, v in summary["settings"]], header=False,
                       widths=[75 * mm, 150 * mm])]

    # ---- the results not proven to conform, the charts, the events
    rows = sections.get("results", {}).get("rows", [])
    failed = [r for r in rows if r["decision"] != "conforms"]
    widths = [10 * mm, 26 * mm, 26 * mm, 18 * mm, 17 * mm, 17 * mm, 17 * mm, 24 * mm, 14 * mm, 12 * mm, 24 * mm, None]

    def result_table(rs: Sequence[Mapping[str, Any]]) -> Any:
        cells = [list(RESULT_HEADER)] + [[*_result_cells(r)[:-1], Paragraph(esc(r["reason"]), small)] for r in rs]
        return grid(cells, widths=widths[:-1] + [width - sum(w for w in widths[:-1])], font=7)

    story += [PageBreak(), Paragraph(f"Results not proven to conform ({len(failed)})", styles["Heading2"])]
    story.append(result_table(failed) if failed else Paragraph("None: every result conforms.", body))
    story += [PageBreak(), Paragraph("The part", styles["Heading2"])]
    image(charts.part_map_png(data.specs, data.results, mesh), page_h - 60 * mm)
    story += [PageBreak(), Paragraph("Timeline of the command streams", styles["Heading2"])]
    image(charts.gantt_png(data.events, data.results, title="the whole run"), 75 * mm)
    ends = sorted(r.sim_time_end for r in data.results if r.sim_time_end is not None)
    if len(ends) > 5:
        image(charts.gantt_png(data.events, data.results, until=ends[4], title="detail: the first 5 measurements"),
              75 * mm)
    two = sections.get("two_arms")
    if two:                 # a run of a two-arm run: both arms' figures (the page draws their chart)
        story += [Paragraph(esc(two["title"]), styles["Heading3"]),
                  grid([["", "", "status"]] + [[Paragraph(esc(c), small) for c in r] for r in two["rows"]],
                       widths=[50 * mm, width - 80 * mm, 30 * mm], font=8)]
    breakdown = sections.get("breakdown")
    if breakdown:
        story += [Paragraph("Cycle-time breakdown", styles["Heading3"]),
                  grid([["", "simulated", "share"]] + [list(r) for r in breakdown["rows"]], font=8)]
    ev = sections.get("events", {}).get("events", [])
    story += [PageBreak(), Paragraph(f"Exceptions and run events ({len(ev)})", styles["Heading2"])]
    if ev:
        cells = [["#", "sim time (s)", "kind", "stream", "spec", "what it recorded"]]
        for e in ev:
            what = "; ".join(f"{k}: {v}" for k, v in e["payload"].items())
            cells.append([str(e["seq"]), _fmt(e["sim_time"], 1), e["kind"], e["stream"] or "", e["spec_id"] or "",
                          Paragraph(esc(what), small)])
        story.append(grid(cells, widths=[12 * mm, 20 * mm, 22 * mm, 16 * mm, 28 * mm, width - 98 * mm], font=7))
    else:
        story.append(Paragraph("No exceptions.", body))
    exceptions = sections.get("exceptions")
    if exceptions:
        story += [PageBreak(), Paragraph(esc(exceptions["title"]), styles["Heading2"]),
                  Paragraph(esc(exceptions["note"]), body), Spacer(1, 2 * mm)]
        header = list(exceptions["header"])
        cells = [[Paragraph(esc(c), small) for c in header]] + \
            [[Paragraph(esc(c), small) for c in r] for r in exceptions["rows"]]
        fixed = [14 * mm, 20 * mm, 24 * mm, 36 * mm, 62 * mm, 28 * mm, 28 * mm, 32 * mm][:len(header) - 1]
        story.append(grid(cells, widths=fixed + [width - sum(fixed)], font=7))
    story += [PageBreak(), Paragraph(f"Every result ({len(rows)})", styles["Heading2"]), result_table(rows)]

    # ---- AS9102 Rev C Form 3, the same form as the workbook (ita report RUN -o fai.xlsx)
    story += [PageBreak(), Paragraph(esc(as9102.TITLE), styles["Heading2"]),
              grid([[k, Paragraph(esc(v), small)] for k, v in as9102.form3_header(data)], header=False,
                   widths=[45 * mm, width - 45 * mm], font=8), Spacer(1, 3 * mm)]
    form_widths = [12 * mm, 34 * mm, 44 * mm, 30 * mm, 52 * mm, 36 * mm, 30 * mm]
    form_widths.append(width - sum(form_widths))
    form = [[Paragraph(esc(c), small) for c in as9102.FORM3_COLUMNS]] + \
        [[Paragraph(esc(c), small) for c in row] for row in as9102.form3_rows(data.results, data.run.id)]
    story.append(grid(form, widths=form_widths, font=7))

    scoring = sections.get("scoring")
    if scoring:
        story += [PageBreak(), Paragraph(esc(scoring["title"]), styles["Heading2"]),
                  Paragraph(esc(scoring["note"]), body), Spacer(1, 2 * mm),
                  grid([list(r) for r in scoring["rows"]], header=False, widths=[120 * mm, 60 * mm]),
                  Spacer(1, 2 * mm),
                  grid([["decision", "truly in tolerance", "truly out of tolerance"]]
                       + [list(r) for r in scoring["confusion"]])]
        by_kind: dict[str, list[float]] = {}
        for tr in (scoring.get("figure") or {}).get("data", []):
            by_kind[tr["name"].rsplit(" (", 1)[0]] = tr["x"]
        image(charts.histogram_png(by_kind), 90 * mm)

    def footer(canvas: Any, doc: Any) -> None:
        canvas.saveState()
        canvas.setFont("Helvetica", 7)
        canvas.drawString(15 * mm, 8 * mm, f"ITA report, run {payload['run']}: part {s['verdict'].upper()}")
        canvas.drawRightString(page_w - 15 * mm, 8 * mm, f"page {doc.page}")
        canvas.restoreState()

    out = io.BytesIO()
    doc = SimpleDocTemplate(out, pagesize=landscape(A4), leftMargin=15 * mm, rightMargin=15 * mm,
                            topMargin=12 * mm, bottomMargin=14 * mm, title=f"ITA report {payload['run']}",
                            author="ITA", subject=f"part verdict: {s['verdict']}")
    doc.build(story, onFirstPage=footer, onLaterPages=footer)
    return out.getvalue()
