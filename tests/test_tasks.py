"""The Top Level's job as knowledge (kb/tasks.pl), planned by the HTN planner and carried
out by the agenda (ita/toplevel/agenda.py): which actions, in which order, and what the
plan becomes when an outcome differs from what it expected.  The Sequence Planner and
the run's state are fakes here: a fixed order of measurements."""

from __future__ import annotations

import time
from collections.abc import Iterator

import pytest

from ita.logic.terms import Term
from ita.planning.operation import format_term
from ita.toplevel.agenda import Agenda, Facts, with_facts

ORDER = [("WT-1", "us_probe_1", 0), ("WT-2", "us_probe_1", 0), ("HD-1", "slra_1", 1), ("HD-2", "slra_1", 1)]


class FakeRun:
    """The attached procedures of a run whose sequence plan is `order`."""

    def __init__(self, order=ORDER, remade_at: int | None = None) -> None:
        self.order = list(order)
        self.done: set[str] = set()
        self.remade_at = remade_at
        self.asked = 0

    def next_measurement(self, cursor):
        self.asked += 1
        k = int(str(cursor))
        if k >= len(self.order):
            return None
        spec, tool, group = self.order[k]
        remade = [k + 1] if self.remade_at == k else []
        return Term("next", (Term("step", (spec, tool, group, remade)), k + 1))

    def nothing_left(self, cursor):
        return [] if int(str(cursor)) >= len(self.order) else None

    def to_measure(self, spec):
        return None if str(spec) in self.done else "true"

    def calibration_due(self, spec, tool):
        return "true" if str(tool).startswith("us_") else None

    def procedures(self):
        return {"next_measurement": self.next_measurement, "nothing_left": self.nothing_left,
                "to_measure": self.to_measure, "calibration_due": self.calibration_due}


@pytest.fixture
def run(knowledge_base) -> Iterator[tuple[Agenda, FakeRun]]:
    fake = FakeRun()
    with knowledge_base.attached(fake.procedures()):
        yield Agenda(knowledge_base, "tasks"), fake


def texts(agenda: Agenda) -> list[str]:
    return [format_term(a.term) for a in agenda.steps]


def carry_out(agenda: Agenda, facts: Facts, upto: str) -> Facts:
    """Carry out actions (doing nothing) until `upto` has been carried out."""
    while (action := agenda.next()) is not None:
        assert agenda.applicable(action, facts), action
        facts = agenda.done(action, facts)
        if format_term(action.term) == upto:
            return facts
    raise AssertionError(f"{upto} never came")


def test_a_whole_part_is_registered_then_measured_in_the_sequence_plans_order_each_probe_calibrated_first(run):
    agenda, _ = run
    agenda.plan(["inspect_part"], {})
    assert texts(agenda) == [
        "register_part", "record_unplaceable",
        "calibrate_probe(us_probe_1)", "measure(WT-1, us_probe_1, 0)", "record(WT-1)", "settle_pending",
        "check_if_due",
        "measure(WT-2, us_probe_1, 0)", "record(WT-2)", "settle_pending", "check_if_due",
        "measure(HD-1, slra_1, 1)", "record(HD-1)", "settle_pending", "check_if_due",
        "measure(HD-2, slra_1, 1)", "record(HD-2)", "settle_pending", "check_if_due",
        "decide_pending", "check_cell", "retake_not_done", "record_leftovers", "end_run(completed)"]


def test_a_last_check_that_finds_the_arm_drifted_measures_again_before_the_end(run):
    """The end of a run checks the cell; when that check (its diagnosis) put the
    measurements since the check before back in the sequence plan, they are measured before
    the run completes (so is what was left not done after a fault put right)."""
    agenda, fake = run
    agenda.plan(["inspect_part"], {})
    facts = carry_out(agenda, {}, "check_cell")
    fake.done |= {"WT-1", "WT-2", "HD-1"}                  # recorded; the check found the arm drifted:
    fake.done.discard("HD-2")                              # HD-2 again
    facts = with_facts(facts, ["remeasuring"])
    agenda.replan_rest(facts)
    assert texts(agenda)[:4] == ["retake_not_done", "requeued", "measure(HD-2, slra_1, 1)", "record(HD-2)"]
    assert texts(agenda)[-5:] == ["decide_pending", "check_cell", "retake_not_done", "record_leftovers",
                                  "end_run(completed)"]


def test_a_reinspection_measures_each_result_again_the_more_accurate_way(knowledge_base):
    """The earlier results decide the way (kb/tasks.pl better_way/3): a position whose
    largest term is its network's frame poses gets 16 approaches; a rib width the SLRA
    left uncertain goes to the probe, which reads the block first; a diameter limited by
    the SLRA's calibration and a thickness not done are measured as before."""
    order = [("HP-1", "slra_1", 1), ("SW-1", "slra_1", 1), ("HD-1", "slra_1", 1), ("WT-1", "us_probe_1", 0)]
    earlier = {"HP-1": ("uncertain", "slra_tool", "hole_position", "network (frame poses and rim fits)", 1),
               "SW-1": ("uncertain", "slra_tool", "stiffener_width", "SLRA calibration (reference workpieces)", 1),
               "HD-1": ("uncertain", "slra_tool", "hole_diameter", "SLRA calibration (reference workpieces)", 1),
               "WT-1": ("not_done", "us_tool", "web_thickness", "none", 1)}
    fake = FakeRun(order)
    procedures = {**fake.procedures(),
                  "earlier": lambda spec: Term("earlier", earlier[str(spec)]),
                  "alternatives": lambda spec: [Term("alt", ("us_tool", "us_probe_1"))] if str(spec) == "SW-1" else []}
    with knowledge_base.attached(procedures):
        agenda = Agenda(knowledge_base, "tasks")
        agenda.plan(["reinspect"], with_facts({}, ["reinspecting"]))
    steps = texts(agenda)
    assert steps[0] == "register_part"                          # the part located on its datums first
    steps = steps[1:]
    assert steps[:4] == ["measure_again(HP-1, more_frames(16), 1)", "record(HP-1)", "settle_pending", "check_if_due"]
    assert steps[4:7] == ["calibrate_probe(us_probe_1)", "measure_again(SW-1, other_sensor(us_probe_1), 1)",
                          "record(SW-1)"]
    assert "measure(HD-1, slra_1, 1)" in steps and "measure(WT-1, us_probe_1, 0)" in steps
    assert "calibrate_probe(us_probe_1)" not in steps[7:]       # read the block once


def test_a_remade_sequence_plan_is_noted_where_it_was_remade(knowledge_base):
    fake = FakeRun(remade_at=2)
    with knowledge_base.attached(fake.procedures()):
        agenda = Agenda(knowledge_base, "tasks")
        agenda.plan(["inspect_part"], {})
    steps = texts(agenda)
    assert steps.index("note_resequence(3)") == steps.index("measure(HD-1, slra_1, 1)") - 1


def test_a_failed_reading_is_handled_then_recorded(run):
    agenda, _ = run
    agenda.plan(["inspect_part"], {})
    facts = with_facts(carry_out(agenda, {}, "measure(WT-1, us_probe_1, 0)"), [Term("failed", ("WT-1",))])
    action = agenda.next()
    assert action is not None and format_term(action.term) == "record(WT-1)"
    assert not agenda.applicable(action, facts)            # a record after a failed reading: plan it again
    assert agenda.replan_parent(facts)
    assert texts(agenda)[:5] == ["handle_exception(WT-1)", "record(WT-1)", "settle_pending", "check_if_due",
                                 "measure(WT-2, us_probe_1, 0)"]
    facts = agenda.done(agenda.steps[0], facts)
    assert "failed(WT-1)" not in facts and agenda.applicable(agenda.steps[0], facts)


def test_a_measurement_another_frame_measured_meanwhile_is_passed_by(run):
    agenda, fake = run
    agenda.plan(["inspect_part"], {})
    facts = carry_out(agenda, {}, "check_if_due")
    facts = carry_out(agenda, facts, "check_if_due")
    fake.done.add("HD-2")                                  # HD-1's frame measured it
    facts = carry_out(agenda, facts, "check_if_due")
    action = agenda.next()
    assert action is not None and format_term(action.term) == "measure(HD-2, slra_1, 1)"
    assert not agenda.applicable(action, facts)
    assert agenda.replan_parent(facts)
    assert texts(agenda) == ["decide_pending", "check_cell", "retake_not_done", "record_leftovers", "end_run(completed)"]


@pytest.mark.parametrize("fact, end", [("interrupted", ["check_cell", "end_run(interrupted)"]),
                                       ("stopped", ["end_run(stopped)"]),
                                       ("alarm", ["check_cell", "end_run(stopped)"])])
def test_an_interrupt_a_stop_or_the_alarm_ends_the_run_without_measuring_more(run, fact, end):
    """An interrupt or the alarm checks the cell first (what is held since the last check
    is recorded when it passes); a STOP ends at once."""
    agenda, _ = run
    agenda.plan(["inspect_part"], {})
    facts = with_facts(carry_out(agenda, {}, "check_if_due"), [fact])
    agenda.replan_rest(facts)
    assert texts(agenda) == end


def test_a_stop_during_a_measurement_leaves_it(run):
    agenda, _ = run
    agenda.plan(["inspect_part"], {})
    facts = with_facts(carry_out(agenda, {}, "calibrate_probe(us_probe_1)"), ["stopped"])
    agenda.replan_rest(facts)                              # measure(WT-1) was under way: not carried out
    assert texts(agenda) == ["end_run(stopped)"]


def test_the_tree_shows_the_job_its_methods_and_the_sequence_planner_asked(run):
    agenda, _ = run
    agenda.plan(["inspect_part"], {})
    nodes = list(agenda.walk())
    assert nodes[0][1].task == "inspect_part" and nodes[0][1].method == "in_sequence"
    asked = [format_term(c) for _, n in nodes for c in n.calls]
    assert any(c.startswith("next_measurement(0, step(WT-1") for c in asked)
    assert {format_term(n.method) for _, n in nodes if not n.primitive} >= {
        "in_sequence", "next_measurement", "nothing_left", "calibrate_first", "round_trip", "recorded", "completed"}


def test_a_whole_part_is_planned_and_a_failure_replans_only_its_measurement(knowledge_base):
    order = [(f"S{i}", "us_probe_1" if i < 100 else "slra_1", 0 if i < 100 else 1) for i in range(1100)]
    fake = FakeRun(order)
    with knowledge_base.attached(fake.procedures()):
        agenda = Agenda(knowledge_base, "tasks")
        t0 = time.perf_counter()
        agenda.plan(["inspect_part"], {})
        whole = time.perf_counter() - t0
        assert len(agenda.steps) == 6 + 1 + 4 * 1100 + 1     # register, record the unplaceable, ...; the end 5
        facts = with_facts(carry_out(agenda, {}, "measure(S500, slra_1, 1)"), [Term("failed", ("S500",))])
        t0 = time.perf_counter()
        assert agenda.replan_parent(facts)
        local = time.perf_counter() - t0
    print(f"whole plan {whole:.3f} s, local replan {local * 1000:.1f} ms")
    assert texts(agenda)[0] == "handle_exception(S500)"


def test_ita_tasks_lists_the_jobs_and_inspect_refuses_an_unknown_one(tmp_path):
    from click.testing import CliRunner

    from ita.cli import main

    listed = CliRunner().invoke(main, ["tasks"])
    assert listed.exit_code == 0 and listed.output.startswith("inspect_part"), listed.output
    refused = CliRunner().invoke(main, ["inspect", "--task", "nope", "--limit", "1", "--runs-dir", str(tmp_path)])
    assert refused.exit_code == 2 and "no job 'nope'" in refused.output and "inspect_part" in refused.output
    assert not any(tmp_path.iterdir())          # nothing made: refused before any work
