"""One count of exceptions (ita.archive.exceptions): every failed plan counted once, by
where it happened, each diagnosis on the exception it explains; the end of `ita inspect`,
`ita diagnosis show` (text and --json), `ita monitor` and the report show the same numbers."""

from __future__ import annotations

import json

from click.testing import CliRunner

from ita.archive import Archive, Event
from ita.archive.exceptions import ExceptionCounts, exception_records


def _exception(at: float, message: str) -> Event:
    return Event("exception", "slra", at, {"message": message, "kind": "exception", "step": 2})


def _diagnosis(at: float, spec: str, exception: str, **more) -> Event:
    return Event("diagnosis", "top", at, {"spec": spec, "exception": exception, "t0": at, "t1": at + 5.0,
                                          "cause": "dirty_window(slra_1)", "tests": [], "recovery": "retried",
                                          "summary": f"{exception}: ...", **more})


def _plan(at: float, spec: str | None, purpose: str | None = None) -> Event:
    payload = {"spec": spec, "macrop": "m", "steps": 3}
    if purpose is not None:
        payload["purpose"] = purpose
    return Event("plan_start", "top", at, payload)


def events() -> list[Event]:
    """A measurement fails; its diagnosis runs a test that fails (its outcome) and a repair;
    the recovery's second attempt fails on another fault, diagnosed in turn (nested); a
    probe's calibration plan fails; a second measurement fails and is diagnosed."""
    return [
        _plan(0.0, "HD-1"), _exception(1.0, "VISION(too_few_pixels)"),
        _diagnosis(1.0, "HD-1", "too_few_pixels"),
        _diagnosis(9.0, "HD-1", "controller_timeout", during="too_few_pixels"),
        _plan(2.0, "HD-1", "test scan_cal_block"), _exception(3.0, "VISION(too_few_pixels)"),
        _plan(4.0, "HD-1", "repair clean(slra_1)"),
        _plan(8.0, "HD-1", "recovery: plan repair"), _exception(9.0, "timeout"),
        _plan(20.0, None, "calibration"), _exception(21.0, "GAUGE(no_echo)"),
        _plan(30.0, "WT-2"), _exception(31.0, "GAUGE(no_contact)"),
        _diagnosis(31.0, "WT-2", "no_contact"),
    ]


def test_each_failed_plan_counts_once_where_it_happened_with_its_own_diagnosis() -> None:
    records = exception_records(events())
    assert [(r.spec, r.where) for r in records] == [("HD-1", "measurement"), ("HD-1", "test"), ("HD-1", "retry"),
                                                    (None, "check"), ("WT-2", "measurement")]
    assert [r.diagnosis["exception"] if r.diagnosis else None for r in records] == [
        "too_few_pixels", None, "controller_timeout", None, "no_contact"]
    assert records[1].within is not None and records[1].within["exception"] == "too_few_pixels"   # the test's
    counts = ExceptionCounts.of(records)
    assert (counts.total, counts.diagnosed) == (5, 3)
    assert counts.text() == ("5 exceptions (2 in measurements, 1 in a recovery's second attempt, 1 in a "
                             "diagnostic test, 1 in a check of the cell); 3 diagnosed")
    assert ExceptionCounts.of([]).text() == "0 exceptions"


def test_every_view_shows_the_same_count(tmp_path) -> None:
    from ita.cli import main
    from ita.cli.inspect import monitor_text
    from ita.report.live import live_state

    runs = tmp_path / "runs"
    with Archive.open(runs / "archive.sqlite") as archive:
        run_id = archive.create_run("bulkhead", total=2)
        archive.record_events(run_id, events())
        state = live_state(archive, run_id)
    text = ExceptionCounts.from_events(events()).text()
    assert state["exception_count"] == 5 and state["exception_counts"]["text"] == text
    assert any(text in line for line in monitor_text(state, columns=400))
    shown = CliRunner().invoke(main, ["diagnosis", "show", run_id, "--runs-dir", str(runs)])
    assert shown.exit_code == 0, shown.output
    assert shown.output.splitlines()[0] == f"run {run_id}: {text}"
    listed = CliRunner().invoke(main, ["diagnosis", "show", run_id, "--runs-dir", str(runs), "--json"])
    assert listed.exit_code == 0, listed.output
    data = json.loads(listed.output)
    assert len(data["exceptions"]) == data["counts"]["exceptions"] == 5          # one entry per counted exception
    assert sum(e["diagnosed"] for e in data["exceptions"]) == data["counts"]["diagnosed"] == 3
    assert data["diagnoses_without_exception"] == []
