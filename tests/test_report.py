"""The HTML report of a run, and the timeline arithmetic behind its Gantt chart."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from archive_synth import fake_specs, record_synthetic_run, true_values

from ita.archive import Archive, Event, RunStatus, timeline
from ita.archive.report import (
    GOAL_HOURS,
    MANUAL_HOURS,
    build_report,
    collect,
    summary,
    write_report,
)


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


def _no_external_references(page: str) -> None:
    assert not re.search(r"""(src|href)\s*=\s*["']?(https?:|//)""", page, re.IGNORECASE)
    assert not re.search(r"url\(\s*['\"]?(https?:|//)", page, re.IGNORECASE)
    assert "<script" not in page.lower() and "<link" not in page.lower() and "@import" not in page


def test_report_is_one_self_contained_page_with_the_summary(run, tmp_path: Path) -> None:
    a, rid, specs, _ = run
    page = build_report(a, rid, specs=specs)
    _no_external_references(page)
    s = summary(collect(a, rid, specs))
    assert s["done"] == 120 and sum(s["counts"].values()) == 120
    assert f"{s['done']} of 120" in page
    assert f"{s['cycle_s'] / 3600:.3f} h" in page and f"{MANUAL_HOURS / s['cycle_h']:.1f}x faster" in page
    assert f"{s['cycle_h'] / GOAL_HOURS:.2f} of the goal time" in page
    for status, n in s["counts"].items():
        assert re.search(rf"{status.replace('_', ' ')}</td><td class=\"num\">{n}<", page), status
    assert s["counts"]["not_done"] == 3 and s["counts"]["does_not_conform"] > 0
    # the charts are inline PNGs: part map, tours, Gantt (whole and detail)
    images = re.findall(r'<img src="data:image/png;base64,[A-Za-z0-9+/=]+" alt="([^"]*)"', page)
    assert {"part map coloured by decision", "tours", "Gantt chart of the command streams",
            "Gantt chart, detail"} <= set(images)
    assert "Scoring" not in page
    out = write_report(tmp_path / "sub" / "r.html", page)
    assert out.read_text(encoding="utf-8") == page


def test_report_lists_the_exceptions_escaped(run) -> None:
    a, rid, specs, _ = run
    page = build_report(a, rid, specs=specs)
    assert "4 exception(s)" in page and page.count("no back-wall echo") >= 3
    assert "&lt;script&gt;alert(1)&lt;/script&gt; collision" in page


def test_scoring_section_only_with_true_values(run) -> None:
    a, rid, specs, truth = run
    page = build_report(a, rid, specs=specs, true_values=truth)
    _no_external_references(page)
    section = page[page.index('<section class="scoring"'):]
    assert "simulation only" in section and 'alt="error histogram"' in section
    assert re.search(r"false accepts[^<]*</td><td class=\"num\">\d+<", section)


def test_a_partial_run_is_projected_to_all_specs(tmp_path: Path) -> None:
    specs = fake_specs(60)
    with Archive.open(tmp_path / "a.sqlite") as a:
        rid = record_synthetic_run(a, specs, true_values(specs), upto=20, status=RunStatus.INTERRUPTED)
        s = summary(collect(a, rid, specs))
        page = build_report(a, rid, specs=specs)
    assert s["done"] == 20 and s["projected_h"] == pytest.approx(s["cycle_h"] * 3)
    assert "projected for all 60 measurements" in page and "20 of 60" in page


def test_a_run_without_events_still_reports(tmp_path: Path) -> None:
    with Archive.open(tmp_path / "a.sqlite") as a:
        rid = a.create_run("empty", total=5)
        page = build_report(a, rid)
    assert "0 of 5" in page and "No commands recorded" in page and "No exceptions" in page


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
    assert parts == {"measuring": 4.0, "tool_change": 3.0, "motion": 2.0, "other": 0.0, "waiting": 0.0,
                     "idle": 1.0}
    assert sum(parts.values()) == 10.0
    busy = timeline.stream_busy(ivs)
    assert busy["arm"] == (7.0, 0.0) and busy["gauge"] == (2.0, 4.0)


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
