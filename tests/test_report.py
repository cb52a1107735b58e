"""The report of a run (summary, verdict, per-feature rows, HTML, PDF), and the timeline
arithmetic behind its Gantt chart."""

from __future__ import annotations

import io
import json
import re
from pathlib import Path

import pytest
from archive_synth import fake_specs, record_synthetic_run, true_values

from ita.archive import Archive, Event, RunStatus, timeline
from ita.errors import InputError
from ita.report import (
    GOAL_HOURS,
    MANUAL_HOURS,
    Verdict,
    build_pdf,
    build_report,
    collect,
    report_format,
    summarize,
    write_report,
)
from ita.report.data import COLUMNS, result_row
from ita.report.sections import report_payload


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory):
    path = tmp_path_factory.mktemp("report") / "archive.sqlite"
    specs = fake_specs(120)
    truth = true_values(specs)
    with Archive.open(path) as a:
        rid = record_synthetic_run(a, specs, truth)
        a.record_event(rid, Event("exception", "arm", 5.0, {"message": "<script>alert(1)</script> collision"}))
    a = Archive.open(path)
    yield a, rid, specs, truth
    a.close()


def _data(page: str) -> dict:
    m = re.search(r'<script id="ita-data" type="application/json">(.*?)</script>', page, re.S)
    return json.loads(m.group(1))


def _no_external_references(page: str) -> None:
    """No reference that loads anything from elsewhere, outside plotly.js (whose text, inlined
    as it ships, names its web site in strings)."""
    from ita.report.assets import asset_text

    plotly = asset_text("plotly.min.js").replace("</script", "<\\/script")
    assert plotly in page
    page = page.replace(plotly, "")
    assert not re.search(r"""(src|href)\s*=\s*["']?(https?:|//)""", page, re.IGNORECASE)
    assert not re.search(r"url\(\s*['\"]?(https?:|//)", page, re.IGNORECASE)
    assert "<link" not in page.lower() and "@import" not in page
    assert not re.search(r"<script[^>]*\ssrc=", page, re.IGNORECASE)


def test_report_is_one_self_contained_page_with_a_verdict(run, tmp_path: Path) -> None:
    a, rid, specs, _ = run
    page = build_report(a, rid, specs=specs)
    _no_external_references(page)
    s = summarize(collect(a, rid, specs))
    assert s.done == 120 and sum(s.counts.values()) == 120 and s.complete
    assert s.verdict is Verdict.REJECT and "do not conform" in s.verdict_reason
    assert "PART REJECT" in page                      # readable without scripts too
    assert f"{MANUAL_HOURS / s.cycle_h:.1f}x faster" in page and f"{s.cycle_h / GOAL_HOURS:.2f} of the goal" in page
    data = _data(page)
    ids = [sec["id"] for sec in data["sections"]]
    assert ids[:2] == ["summary", "results"] and {"part3d", "gantt", "breakdown", "events"} <= set(ids)
    assert "scoring" not in ids and "Scoring" not in page
    assert "window.Plotly" in page or "Plotly" in page  # plotly.js inlined
    out = write_report(tmp_path / "sub" / "r.html", page, make_dirs=True)
    assert out.read_text(encoding="utf-8") == page


def test_rows_carry_deviation_u_over_tolerance_and_a_reason_for_every_unproven(run) -> None:
    a, rid, _, _ = run
    rows = [result_row(r) for r in a.results(rid)]
    assert set(rows[0]) == set(COLUMNS)
    for row in rows:
        if row["value"] is not None:
            assert row["deviation"] == pytest.approx(row["value"] - row["nominal"])
            assert row["U_over_tolerance"] == pytest.approx(row["U"] / (row["upper"] - row["lower"]))
        if row["decision"] != "conforms":
            assert row["reason"], row
    uncertain = [r for r in rows if r["decision"] == "uncertain"]
    assert uncertain and all("within U" in r["reason"] or "half the tolerance" in r["reason"] for r in uncertain)


def test_events_section_lists_exceptions_escaped(run) -> None:
    a, rid, specs, _ = run
    page = build_report(a, rid, specs=specs)
    events = next(sec for sec in _data(page)["sections"] if sec["id"] == "events")
    assert sum(1 for e in events["events"] if e["kind"] == "exception") == 4
    assert "<script>alert(1)" not in page and "\\u003cscript\\u003ealert(1)" in page


def test_scoring_section_only_with_true_values(run) -> None:
    a, rid, specs, truth = run
    page = build_report(a, rid, specs=specs, true_values=truth)
    _no_external_references(page)
    scoring = next(sec for sec in _data(page)["sections"] if sec["id"] == "scoring")
    assert "simulation only" in scoring["title"] and scoring["figure"]["data"]
    kinds = {tr["name"].split(" (")[0] for tr in scoring["figure"]["data"]}
    assert kinds == {"web_thickness", "hole_diameter"}          # one histogram per kind
    assert any(r[0].startswith("false accepts") for r in scoring["rows"])


def test_a_partial_run_is_extrapolated_not_compared(tmp_path: Path) -> None:
    specs = fake_specs(60)
    with Archive.open(tmp_path / "a.sqlite") as a:
        rid = record_synthetic_run(a, specs, true_values(specs), upto=20, status=RunStatus.INTERRUPTED)
        s = summarize(collect(a, rid, specs))
        page = build_report(a, rid, specs=specs)
    assert s.done == 20 and not s.complete and s.verdict in (Verdict.INCOMPLETE, Verdict.REJECT)
    assert s.projected_h == pytest.approx(s.cycle_h * 3) and s.speedup_manual is None and s.ratio_goal is None
    static = page[page.index('<div id="static-summary">'):page.index('<div id="report">')]
    assert "extrapolated (not measured)" in static and "faster" not in static and "20 of 60" in static
    assert s.verdict is Verdict.REJECT or "40 of 60 specs have no result" in s.verdict_reason


def test_verdicts() -> None:
    from ita.report.data import verdict_of

    assert verdict_of({"conforms": 5}, 5)[0] is Verdict.ACCEPT
    assert verdict_of({"conforms": 4, "uncertain": 1}, 5)[0] is Verdict.INCOMPLETE
    assert verdict_of({"conforms": 4}, 5)[:2] == (Verdict.INCOMPLETE, "1 of 5 specs have no result")
    assert verdict_of({"conforms": 3, "does_not_conform": 1}, 5)[0] is Verdict.REJECT


def test_a_run_without_events_still_reports(tmp_path: Path) -> None:
    with Archive.open(tmp_path / "a.sqlite") as a:
        rid = a.create_run("empty", total=5)
        page = build_report(a, rid)
        payload = report_payload(collect(a, rid))
    assert "0 of 5" in page and "No commands recorded" in page
    assert next(sec for sec in payload["sections"] if sec["id"] == "events")["note"] == "No exceptions."


def test_pdf_has_the_verdict_on_page_one(run) -> None:
    from pypdf import PdfReader

    a, rid, specs, truth = run
    pdf = build_pdf(a, rid, specs=specs, true_values=truth)
    reader = PdfReader(io.BytesIO(pdf))
    first = reader.pages[0].extract_text()
    assert "PART REJECT" in first and "do not conform" in first and "manual method" in first
    assert len(reader.pages) > 4
    assert any("Scoring against the as-built part" in p.extract_text() for p in reader.pages[-3:])
    # AS9102 Form 3 as pages of the PDF: the header fields and one row per result
    texts = [p.extract_text() for p in reader.pages]
    start = next(i for i, t in enumerate(texts) if "AS9102 Rev C, Form 3" in t)
    form = "\n".join(t for t in texts[start:] if "Scoring against the as-built part" not in t)
    assert "AS9102 Rev C, Form 3" in form and "4. FAIR Number" in form and rid in form
    missing = [r.spec_id for r in a.results(rid) if r.spec_id not in form]
    assert not missing, (missing, form[:3000])


def test_report_formats_by_extension() -> None:
    assert report_format("a.html") == "html" and report_format("A.PDF") == "pdf"
    with pytest.raises(InputError, match=".html .*or .pdf"):
        report_format("r.txt")


# ---------------------------------------------------------------------- timeline
def ev(kind: str, stream: str, t: float, **payload) -> Event:
    return Event(kind, stream, t, payload)


def test_commands_end_at_their_reply_waits_at_their_continue() -> None:
    events = [ev("command", "arm", 0.0, cmd=1, name="move_to"),
              ev("wait", "gauge", 0.0),
              ev("command", "slra", 1.0, cmd=2, name="scan", duration=2.0),
              ev("reply", "arm", 4.0, cmd=1),
              ev("continue", "gauge", 4.0),
              ev("command", "gauge", 4.0, cmd=3, category="measuring"),
              ev("reply", "gauge", 6.0, cmd=3),
              ev("tool_change", "arm", 6.0, duration=3.0)]
    ivs = timeline.intervals(events)
    got = [(iv.stream, iv.start, iv.end, iv.category) for iv in ivs]
    assert got == [("arm", 0.0, 4.0, "motion"), ("gauge", 0.0, 4.0, "waiting"),
                   ("slra", 1.0, 3.0, "measuring"), ("gauge", 4.0, 6.0, "measuring"),
                   ("arm", 6.0, 9.0, "tool_change")]
    assert timeline.span(events) == (0.0, 9.0)
    parts = timeline.breakdown(ivs, 0.0, 10.0)
    # 0-1 motion, 1-3 measuring (slra beats the arm's motion), 3-4 motion, 4-6 measuring, 6-9 tool change
    assert parts == {"exceptions": 0.0, "measuring": 4.0, "tool_change": 3.0, "motion": 2.0, "other": 0.0,
                     "waiting": 0.0, "idle": 1.0}
    assert sum(parts.values()) == 10.0
    busy = timeline.stream_busy(ivs)
    assert busy["arm"] == (7.0, 0.0) and busy["gauge"] == (2.0, 4.0)
    # an exception handled from 5 to 7.5 s: that time is the exceptions', whatever the streams did
    handled = events + [ev("diagnosis", "top", 5.0, t0=5.0, t1=7.5, exception="no_echo")]
    parts = timeline.breakdown(timeline.intervals(handled), 0.0, 10.0)
    assert parts["exceptions"] == 2.5 and parts["measuring"] == 3.0 and parts["tool_change"] == 1.5
    assert sum(parts.values()) == 10.0


def test_waiting_counts_when_no_stream_is_busy_and_open_intervals_close() -> None:
    events = [ev("wait", "arm", 0.0, on="operator"), ev("continue", "arm", 5.0),
              ev("command", "arm", 5.0, name="go_home"),           # no reply: ends at the next command
              ev("command", "arm", 7.0, name="frobnicate")]        # nor this: ends at the run's end
    ivs = timeline.intervals(events, run_end=8.0)
    assert [(iv.start, iv.end, iv.category) for iv in ivs] == [(0.0, 5.0, "waiting"), (5.0, 7.0, "motion"),
                                                                (7.0, 8.0, "other")]
    assert timeline.breakdown(ivs, 0.0, 8.0)["waiting"] == 5.0


def test_plan_intervals_pair_start_and_end_per_spec() -> None:
    events = [ev("plan_start", "top", 0.0, spec="a"), ev("plan_end", "top", 3.0, spec="a"),
              ev("plan_start", "top", 3.0, spec="b")]
    assert [(iv.label, iv.start, iv.end) for iv in timeline.plan_intervals(events, 10.0)] == [
        ("a", 0.0, 3.0), ("b", 3.0, 10.0)]


def test_a_limited_run_whose_part_is_gone_is_never_a_whole_part(tmp_path: Path) -> None:
    """`ita inspect --limit 3`, every result conforming, then the part directory removed:
    the report cannot count the part's specs, so it must not call the part accepted nor
    compare the run with the manual method as if it were whole."""
    from ita.archive import Result

    specs = [s for s in fake_specs(10) if s.kind == "hole_diameter"][:3]
    with Archive.open(tmp_path / "a.sqlite") as a:
        rid = a.create_run("gone", tmp_path / "no-such-part", total=3, settings={"limit": 3})
        for s in specs:
            a.record_result(rid, Result.measured(s, s.nominal, 0.001, tool="slra_1"))
        a.set_status(rid, RunStatus.COMPLETED)
        s = summarize(collect(a, rid))
    assert s.counts["conforms"] == 3
    assert s.verdict is Verdict.INCOMPLETE and "limited to the first 3" in s.verdict_reason
    assert not s.complete and s.speedup_manual is None and s.ratio_goal is None
    assert s.projected_h is None and not s.part_known      # no whole-part figure from an unknown part
