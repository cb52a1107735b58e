"""The components' graphics in the report's sections: the Sequence Planner's tours on the
part (the next measurement marked while the run goes) and the Exception Handler's test
trees."""

from __future__ import annotations

from archive_synth import fake_specs, record_synthetic_run, true_values

from ita.archive import Archive, Event, RunStatus, archive_path
from ita.report.data import collect
from ita.report.sections import report_payload


def _sections(tmp_path, status: RunStatus, upto: int | None = None) -> dict:
    specs = fake_specs(40)
    order = [s.id for s in sorted(specs, key=lambda s: s.kind != "web_thickness")]     # the run's order
    with Archive.open(archive_path(tmp_path)) as a:
        rid = record_synthetic_run(a, specs, true_values(specs), status=status, upto=upto, settings={"specs": order})
        a.record_event(rid, Event("diagnosis", "top", 5.0, {
            "spec": order[0], "exception": "no_echo", "posterior": [["dry_couplant", 0.6]],
            "tests": [{"test": "read_cal_block", "outcome": "ok", "estimated_s": 9.0, "seconds": 8.0,
                       "posterior": [["dry_couplant", 0.6]]}], "cause": "dry_couplant", "recovery": "squirted"}))
        data = collect(a, rid, specs)
    return {s["id"]: s for s in report_payload(data)["sections"] if "id" in s}, order


def test_the_tours_are_drawn_per_tool_and_the_test_trees_per_diagnosis(tmp_path) -> None:
    sections, _ = _sections(tmp_path, RunStatus.COMPLETED)
    tours = sections["tours"]
    assert tours["kind"] == "figure" and len(tours["table"]["rows"]) == len(tours["figure"]["data"]) == 2
    assert not any(t["name"].startswith("next") for t in tours["figure"]["data"])        # the run has ended
    trees = sections["diagnoses"]["trees"]
    assert len(trees) == 1 and trees[0]["cause"] == "dry_couplant" and trees[0]["tests"][0]["posterior"]


def test_while_the_run_goes_the_tours_show_what_is_left_and_the_next(tmp_path) -> None:
    sections, order = _sections(tmp_path, RunStatus.RUNNING, upto=25)
    traces = {t["name"].split(":")[0].split(" (")[0]: t for t in sections["tours"]["figure"]["data"]}
    assert "still to measure" in traces and len(traces["still to measure"]["x"]) == 15
    assert traces["next"]["name"] == f"next: {order[25]}"


def test_the_gantt_charts_marks_share_a_label_when_close_and_labels_never_lie_on_each_other() -> None:
    from ita.report.figures import _mark_labels

    marks = [Event("exception", "slra", 100.0 + 0.1 * k, {}) for k in range(10)] + \
        [Event("recovery", "top", 400.0, {}), Event("exception", "gauge", 420.0, {}), Event("stop", "top", 900.0, {})]
    labels = _mark_labels(marks, gap=30.0)
    assert [a["text"] for a in labels] == ["EXCEPTION x10", "2 EVENTS", "STOP"]
    assert "100.9 s exception" in labels[0]["hovertext"]
    for a, b in zip(labels, labels[1:]):            # neighbours at two heights, or far apart
        assert a["y"] != b["y"] or b["x"] - a["x"] >= 30.0


def test_an_arms_zone_claims_are_spans_held_and_spans_waited() -> None:
    """The conductor's record of one arm (granted, waited, continued, cleared) as the two
    arms' Gantt chart draws it: a held span from each grant or continue to its clear, a
    waiting span from each wait to its continue."""
    from ita.report.figures import zone_spans

    held, waits = zone_spans([[0.0, "grant", 5], [2.0, "clear", 5], [3.0, "wait", 0], [7.5, "continue", 4],
                              [9.0, "clear", 4], [9.0, "grant", 2], [9.5, "clear", 2], [10.0, "done", 0]])
    assert held == [(0.0, 2.0), (7.5, 9.0), (9.0, 9.5)]
    assert waits == [(3.0, 7.5)]


def test_the_two_arm_gantt_chart_has_a_lane_per_arm_and_stream_and_per_arm_its_zones() -> None:
    from ita.archive.model import Event
    from ita.report.figures import two_arm_gantt_figure

    def run(arm: str, offset: float) -> list[Event]:
        return [Event("command", "arm", offset, {"cmd": 1, "name": "move", "category": "motion", "duration": 2.0}),
                Event("reply", "arm", offset + 2.0, {"cmd": 1, "status": "ok"}),
                Event("zones", "top", 10.0, {"events": [[offset, "wait", 0], [offset + 1.0, "continue", 3],
                                                        [offset + 3.0, "clear", 3]]})]

    fig = two_arm_gantt_figure([("a", run("a", 0.0)), ("b", run("b", 4.0))])
    lanes = fig["layout"]["yaxis"]["categoryarray"]
    assert set(lanes) == {"a arm", "a zones", "b arm", "b zones"}
    waiting = next(t for t in fig["data"] if t["name"] == "waiting for the other arm's zones")
    assert [y for y in waiting["y"] if y] == ["a zones", "a zones", "b zones", "b zones"]
