"""The Exception Handler in the simulated cell: each exception diagnosed to the fault
switched on, the world put right, the measurement recovered (or honestly not done)."""

from __future__ import annotations

import numpy as np
import pytest

from ita.planning import WorldState
from ita.sim.faults import FaultSet
from ita.task import MeasureStatus, measure_one


@pytest.fixture(scope="module")
def session(builtin_part):
    from ita.task import open_session

    s = open_session(None, seed=11)
    yield s
    s.close()


@pytest.fixture(scope="module")
def handler(session):
    from ita.diagnosis import ExceptionHandler

    return ExceptionHandler(session, learn=False)


@pytest.fixture(scope="module")
def arm() -> dict[str, WorldState]:
    return {"state": WorldState(arm="t3")}


def _first(session, tool: str, kind: str | None = None, skip: int = 0) -> str:
    ids = [i for g in session.plan.groups if g.tool == tool for i in g.order
           if kind is None or session.specs[i].kind.value == kind]
    return ids[skip]


def _fail_and_handle(session, handler, arm, spec_id: str, tool: str, faults: FaultSet):
    """Measure with `faults` switched on; the handler's answer (the arm state kept)."""
    session.kb.once("world", "reset_world")
    session.world.faults = faults
    out = measure_one(session, spec_id, arm["state"], tool)
    assert out.status is MeasureStatus.NOT_DONE, f"{spec_id} did not fail with {faults.names()}"
    handled = handler.handle(out)
    assert handled is not None
    arm["state"] = handled.outcome.state
    return out, handled


CASES = [  # fault, target, tool, exception, isolated cause, measured after recovery
    ("broken_probe", "us_probe_1", "us_probe_1", "no_echo", "broken_probe(us_probe_1)", True),
    ("worn_probe", "us_probe_1", "us_probe_1", "doubled_thickness", "worn_probe(us_probe_1)", True),
    ("empty_couplant", "couplant_station", "us_probe_1", "no_couplant_film", "empty_couplant_station", True),
    ("dry_couplant", "us_probe_1", "us_probe_1", "no_couplant_film", "dry_couplant(us_probe_1)", True),
    ("sensor_garbage", "us_gauge", "us_probe_1", "corrupt_reply", "sensor_cable_fault(gauge)", True),
    ("transient", "us_gauge", "us_probe_1", "no_echo", "transient_glitch", True),
    ("controller_silent", "controller", "us_probe_1", "controller_timeout", "controller_not_answering", True),
    ("dirty_window", "slra_1", "slra_1", "too_few_pixels", "dirty_window(slra_1)", True),
    ("tilted_probe", "us_probe_1", "us_probe_1", "misaligned", "tilted_probe(us_probe_1)", True),
    ("slra_failed", "slra_1", "slra_1", "too_few_pixels", "slra_failed(slra_1)", True),
]


@pytest.mark.parametrize("fault,target,tool,exception,cause,measured", CASES, ids=[c[0] for c in CASES])
def test_each_exception_is_diagnosed_to_the_fault_switched_on(session, handler, arm, fault, target, tool,
                                                              exception, cause, measured):
    kind = "web_thickness" if tool.startswith("us_") else "hole_diameter"
    spec_id = _first(session, tool, kind, skip=CASES.index(next(c for c in CASES if c[0] == fault)))
    _, handled = _fail_and_handle(session, handler, arm, spec_id, tool, FaultSet().with_fault(fault, target))
    d = handled.diagnosis
    assert d.exception == exception
    assert d.cause == cause, d.summary
    assert d.tests, "a cause was isolated without a test"
    assert (handled.outcome.status is MeasureStatus.MEASURED) is measured, handled.outcome.reason
    if measured:   # the cell was put right, or the tool set aside
        still = session.world.faults.names()
        assert f"{fault}@{target}" not in still or fault in ("broken_probe", "worn_probe", "slra_failed")
        truth = _truth(session)[spec_id]
        v = handled.outcome.value
        assert abs(v.value - truth) <= max(2.0 * v.u, 0.02)
    session.world.faults = FaultSet()


def test_a_recovery_added_in_the_knowledge_alone_a_tilted_probe_straightened_by_a_person(session, handler, arm):
    """The recovery added to show that a new one is one place in kb/faults.pl: a probe
    knocked crooked in its holder (the simulator's TILTED_PROBE) tilts every reading, on
    the part and on the calibration block; the block's reading and the reference feature
    (the arm is where it should be) tell it from a drifted arm and a displaced part; its
    recovery, ``achieve(probe_straightened(P))``, is planned by the Operation Planner onto
    the person's stream (kb/operators.pl straighten_probe, ita/devices/person.py), the run
    waits the simulated person's two minutes, and the measurement is made."""
    from ita.sim.person import SECONDS

    spec_id = _first(session, "us_probe_1", "web_thickness", skip=17)
    _, handled = _fail_and_handle(session, handler, arm, spec_id, "us_probe_1",
                                  FaultSet().with_fault("tilted_probe", "us_probe_1"))
    d = handled.diagnosis
    assert d.exception == "misaligned" and d.cause == "tilted_probe(us_probe_1)", d.summary
    assert {t.test: t.outcome for t in d.tests}.get("measure_reference_feature") == "ok", d.summary
    assert d.actions == ("achieve(probe_straightened(us_probe_1))",)
    repairs = [(label, plan, report) for label, plan, report in handled.executed if label.startswith("repair ")]
    assert [label for label, _, _ in repairs] == ["repair probe_straightened(us_probe_1)"]
    _, plan, report = repairs[0]
    assert [st.text for st in plan.steps] == ["straighten_probe(technician, us_probe_1)"]
    assert report.ok and [str(o.command.stream) for o in report.outcomes] == ["person(technician)"]
    assert report.makespan == pytest.approx(SECONDS["straighten_probe"])
    assert "tilted_probe@us_probe_1" not in session.world.faults.names()
    assert handled.outcome.status is MeasureStatus.MEASURED, handled.outcome.reason
    v = handled.outcome.value
    assert abs(v.value - _truth(session)[spec_id]) <= max(2.0 * v.u, 0.02)
    session.world.faults = FaultSet()


def test_a_person_is_a_device_the_executive_drives(session, arm):
    """A person's job is planned and executed like the cell's: the Operation Planner plans
    obstacles_removed(cell) to the person's stream, the Plan Executive waits for the reply,
    the simulator gives the person's answer (the time taken, the obstacle gone)."""
    from ita.sim.person import SECONDS
    from ita.task import execute_goals

    world = session.world
    world.add_obstacle("box_far_away", (4.0, 4.0, 0.5), (0.1, 0.1, 0.1))
    t0 = session.clock.now
    plan, report, state, note = execute_goals(session, [_term("obstacles_removed", "cell")], arm["state"], name="t")
    assert note == "" and [st.text for st in plan.steps] == ["remove_obstacles(technician)"]
    assert report.ok and str(report.outcomes[0].command.stream) == "person(technician)"
    assert session.clock.now - t0 == pytest.approx(SECONDS["remove_obstacles"])
    assert not world.obstacles
    assert (state.pose, state.holding) == (arm["state"].pose, arm["state"].holding)
    assert session.person.done[-1].startswith("1 obstacle(s) removed")


def test_a_broken_bent_probe_is_diagnosed_and_replaced_from_the_stores(session, handler, arm):
    """The probe bent 90 degrees is a probe to the Exception Handler too: its dead element is
    found by the tests (its own reading of the calibration block), it is marked broken and,
    with no spare bent probe in the rack, a person replaces it; the wall is then measured."""
    spec_id = "FT-OFL01-W1"
    assert session.planned_tool(spec_id) == "us_probe_90"
    _, handled = _fail_and_handle(session, handler, arm, spec_id, "us_probe_90",
                                  FaultSet().with_fault("broken_probe", "us_probe_90"))
    d = handled.diagnosis
    assert d.exception == "no_echo" and d.cause == "broken_probe(us_probe_90)", d.summary
    assert d.tests, "a cause was isolated without a test"
    assert d.updates[0] == "world: tool_condition(us_probe_90, broken)"           # no spare: a person replaces it
    assert d.updates[1].startswith("achieved tool_replaced(us_probe_90): replace_tool(technician, us_probe_90)")
    assert d.updates[2] == "world: tool_condition(us_probe_90, ok)"
    assert handled.outcome.status is MeasureStatus.MEASURED, handled.outcome.reason
    v = handled.outcome.value
    assert abs(v.value - _truth(session)[spec_id]) <= max(2.0 * v.u, 0.02)
    session.kb.once("world", "reset_world")
    session.world.faults = FaultSet()


def _truth(session) -> dict[str, float]:
    from ita.scoring.truth import true_values

    return true_values(session.part.directory)


def test_a_doubled_reading_never_becomes_a_result(session, handler, arm):
    """Both probes worn: every reading is doubled; the measurement ends not done, never a value."""
    spec_id = _first(session, "us_probe_1", "web_thickness", skip=9)
    faults = FaultSet().with_fault("worn_probe", "us_probe_1").with_fault("worn_probe", "us_probe_2")
    out, handled = _fail_and_handle(session, handler, arm, spec_id, "us_probe_1", faults)
    assert out.report.failure.reply.payload.args[0] == "doubled"
    assert handled.outcome.status is MeasureStatus.NOT_DONE
    assert handled.outcome.value is None or not handled.outcome.value.ok or \
        handled.outcome.status is not MeasureStatus.MEASURED
    assert "diagnosis" in handled.outcome.reason
    session.world.faults = FaultSet()


def test_a_test_that_needs_the_probe_with_the_slra_in_hand_plans_and_prices_the_tool_change(session, handler,
                                                                                            arm):
    from ita.diagnosis.tests import Situation

    session.kb.once("world", "reset_world")
    bench = handler.bench
    spec_id = _first(session, "slra_1")
    held = session.world.held
    situation = Situation(spec_id, "slra_1", "slra_tool", "too_few_pixels", arm["state"])
    own = handler.knowledge.tests()["read_cal_block"].seconds
    cost = bench.cost("read_cal_block", situation)
    if held is not None and not held.startswith("us_"):
        assert cost > own + 5.0                     # a tool change priced in
    assert bench.cost("retry_reading", situation) is None   # a probe retry of an SLRA view does not apply
    plan, report, state, _ = bench.execute_goals([_term("calibrated", "us_probe_1")], situation.state, name="t")
    arm["state"] = state
    actions = [s.action for s in plan.steps]
    assert "us_check_calibration" in actions
    if held is not None and held != "us_probe_1":
        assert "pick_up" in actions and actions.index("pick_up") < actions.index("us_check_calibration")


def _term(name: str, *args):
    from ita.logic.terms import Term

    return Term(name, tuple(args))


def test_replanning_and_repair_each_give_a_valid_plan_from_a_mid_plan_failure(session, arm):
    """A plan stopped at its measuring step: plan repair keeps its unfinished steps after a
    prefix for their preconditions; replanning plans afresh; both measure."""
    from ita.task.measure import execute_measurement

    spec_id = _first(session, "us_probe_1", "web_thickness", skip=11)
    session.kb.once("world", "reset_world")
    session.world.faults = FaultSet().with_fault("transient", "us_gauge")
    out = measure_one(session, spec_id, arm["state"], "us_probe_1")
    session.world.faults = FaultSet()
    assert out.status is MeasureStatus.NOT_DONE and out.report.failure.command.name == "MEASURE"
    repaired = session.planner.repair_plan(out.plan, out.report.failure.completed, out.state)
    assert repaired is not None and repaired.steps[-1].action == "us_measure"
    kept = [s for s in out.plan.steps if s.number not in set(out.report.failure.completed)]
    assert [(s.action, s.args) for s in repaired.steps[-len(kept):]] == [(s.action, s.args) for s in kept]
    done = execute_measurement(session, spec_id, "us_probe_1", repaired)
    assert done.status is MeasureStatus.MEASURED
    again = measure_one(session, spec_id, done.state, "us_probe_1")
    assert again.status is MeasureStatus.MEASURED
    arm["state"] = again.state


def test_learned_frequencies_persist_and_change_the_first_test(session, tmp_path):
    from ita.diagnosis import FaultCounts
    from ita.diagnosis.knowledge import FaultKnowledge

    path = tmp_path / "counts.json"
    kn = FaultKnowledge(session.kb)
    context = [_term("=", "probe", "us_probe_1"), _term("=", "device", "gauge")]
    tests = [("check_couplant_station", 9.0), ("read_cal_block", 12.0), ("retry_reading", 5.0)]
    before = kn.step("no_couplant_film", context, FaultCounts.load(path).causes, [], tests)
    for _ in range(40):       # the cell has seen many one-off glitches: a retry is the cheapest bet
        FaultCounts.record("no_couplant_film", "transient_glitch", path)
    counts = FaultCounts.load(path)
    assert counts.causes["transient_glitch"] == 40 and counts.exceptions["no_couplant_film"] == 40
    after = kn.step("no_couplant_film", context, counts.causes, [], tests)
    assert before.choice == ("test", "check_couplant_station")
    assert after.choice == ("test", "retry_reading")
    assert dict(after.posterior)["transient_glitch"] > dict(before.posterior)["transient_glitch"]


def test_a_run_with_a_broken_probe_finishes_its_thicknesses_with_the_spare(session, tmp_path):
    """The Top Level with a broken us_probe_1 from the start: the handler marks it, the
    Sequence Planner resequences to the spare, every thickness is measured with it."""
    from ita.archive import Archive
    from ita.sim.inject import FaultInjector, InjectionPlan
    from ita.task import open_session
    from ita.toplevel import RunSignals, TopLevel

    session = open_session(None, seed=11)     # a fresh cell: the arm at home with no tool
    probe = next(g for g in session.plan.groups if g.tool == "us_probe_1")
    ids = [i for i in probe.order if session.specs[i].kind.value == "web_thickness"][20:25]
    session.kb.once("world", "reset_world")
    session.world.faults = FaultSet()
    plan = InjectionPlan.parse(0.0, None, ["broken_probe@us_probe_1:after=0"], seed=1)
    injector = FaultInjector(session.world, plan, tmp_path / "faults.jsonl", poses=session.reasoner)
    session.arm.injector = session.slra.injector = injector
    try:
        with Archive.open(tmp_path / "archive.sqlite") as archive:
            run_id = archive.create_run("bulkhead", session.part.directory, seed=11,
                                        settings={"specs": ids}, total=len(ids))
            summary = TopLevel(session, archive, run_id, RunSignals(message=None)).run()
            results = archive.results(run_id)
            diagnoses = archive.events(run_id, kinds=["diagnosis"])
    finally:
        session.kb.once("world", "reset_world")
        session.close()
    assert summary.status == "completed"
    assert {r.spec_id for r in results} == set(ids)
    assert all(r.outcome.value == "measured" and r.tool == "us_probe_2" for r in results), \
        [(r.spec_id, r.outcome.value, r.tool, r.reason) for r in results]
    assert [d.payload["cause"] for d in diagnoses] == ["broken_probe(us_probe_1)"]


def test_both_slras_failed_the_first_set_aside_the_second_replaced_by_a_person(session, handler, arm):
    """A failed laser is no dirty window: wiping the window and scanning the calibration
    block again still returns nothing.  slra_1 fails: it is marked broken and the
    measurement retried with the spare, slra_2, which has failed too: that retry's failure
    is diagnosed in turn, and with no spare left a person replaces slra_2 from the stores;
    the measurement is made with it."""
    spec_id = _first(session, "slra_1", "hole_diameter", skip=20)
    faults = FaultSet().with_fault("slra_failed", "slra_1").with_fault("slra_failed", "slra_2")
    _, first = _fail_and_handle(session, handler, arm, spec_id, "slra_1", faults)
    assert first.diagnosis.cause == "slra_failed(slra_1)", first.diagnosis.summary
    assert [t.outcome for t in first.diagnosis.tests][-1:] == ["too_few_pixels"]
    assert first.retry_failed and first.outcome.tool == "slra_2", first.diagnosis.recovery
    second = handler.handle(first.outcome)
    arm["state"] = second.outcome.state
    assert second.diagnosis.cause == "slra_failed(slra_2)", second.diagnosis.summary
    assert any("replace_tool(technician, slra_2)" in u for u in second.diagnosis.updates), second.diagnosis.updates
    assert second.outcome.status is MeasureStatus.MEASURED and second.outcome.tool == "slra_2", second.outcome.reason
    assert session.world.faults.names() == ["slra_failed@slra_1"]          # set aside, not repaired
    session.world.faults = FaultSet()


def test_a_second_fault_met_while_handling_is_diagnosed_on_its_own_and_both_put_right(session, handler, arm):
    """The window dirty (the view fails), then the controller stops answering while the
    Exception Handler tests and cleans: the controller is diagnosed and reset as a fault
    of its own, the window still found dirty and cleaned, the measurement made."""
    spec_id = _first(session, "slra_1", "hole_diameter", skip=12)
    session.kb.once("world", "reset_world")
    session.world.faults = FaultSet().with_fault("dirty_window", "slra_1")
    out = measure_one(session, spec_id, arm["state"], "slra_1")
    assert out.status is MeasureStatus.NOT_DONE
    session.world.faults = session.world.faults.with_fault("controller_silent", "controller")
    handled = handler.handle(out)
    arm["state"] = handled.outcome.state
    assert handled.diagnosis.cause == "dirty_window(slra_1)", handled.diagnosis.summary
    assert [d.cause for d in handled.nested] == ["controller_not_answering"], [d.summary for d in handled.nested]
    assert handled.nested[0].exception == "controller_timeout"
    assert handled.outcome.status is MeasureStatus.MEASURED, handled.outcome.reason
    assert session.world.faults.names() == []
    session.world.faults = FaultSet()


def test_kb_why_explains_a_recorded_diagnosis(knowledge_base, tmp_path, monkeypatch):
    """`ita diagnosis show` prints, for each cause found, the `ita kb why` goal whose proof
    shows the exception's causes and the test results that leave only that one."""
    from click.testing import CliRunner

    from ita.cli import main
    from ita.cli.diagnosis import why_goal

    monkeypatch.setenv("ITA_HOME", str(tmp_path / "home"))
    recorded = {"exception": "too_few_pixels", "context": {"device": "slra_1", "slra": "slra_1", "tool": "slra_1"},
                "tests": [{"test": "rescan_second_standoff", "outcome": "fails_again"},
                          {"test": "measure_reference_feature", "outcome": "not_run"},
                          {"test": "scan_cal_block", "outcome": "too_few_pixels"},
                          {"test": "clean_and_scan_cal_block", "outcome": "ok"}], "cause": "dirty_window(slra_1)"}
    goal = why_goal(recorded)
    assert goal == ("faults:isolated(too_few_pixels, [device=slra_1, slra=slra_1, tool=slra_1], "
                    "[rescan_second_standoff-fails_again, scan_cal_block-too_few_pixels, "
                    "clean_and_scan_cal_block-ok], Cause)")
    result = CliRunner().invoke(main, ["kb", "why", goal])
    assert result.exit_code == 0, result.output
    first = result.output.splitlines()[0]
    assert "dirty_window(slra_1))" in first                       # the cause it isolates
    assert "raises(" in result.output or "candidate_causes(" in result.output


def test_an_injected_obstacle_is_ahead_of_the_arm_never_against_it(session, tmp_path):
    """An obstacle drawn for a MOVE goes where the arm is going; not where it would touch or
    nearly touch the arm where it stands (a box a hair from the stopped arm blocked every
    later move and every diagnosis test: ten measurements in a row not done)."""
    from types import SimpleNamespace

    from ita.sim.inject import FaultInjector, InjectionPlan

    world = session.world
    q0 = np.array(world.q, dtype=float)

    class Poses:
        def __init__(self, q):
            self.q = q

        def resolve(self, name, held):
            return SimpleNamespace(q=self.q)

    def place(dq: float) -> bool:
        target = q0 + np.array([dq, 0.0, 0.0, 0.0, 0.0, 0.0])
        injector = FaultInjector(world, InjectionPlan.parse(0.0, None, [], seed=1), tmp_path / "f.jsonl",
                                 poses=Poses(target))
        placed = injector._place_obstacle("obstacle_t", SimpleNamespace(name="MOVE", args=("a", "b")))
        if placed:
            world.remove_obstacle("obstacle_t")
        return placed

    def gap(dq: float) -> float:
        """Margin (m) at which a box for q0 + dq on joint 1 first touches the arm as it stands."""
        world.add_obstacle("probe_box", world.tcp_pose(q0 + np.array([dq, 0, 0, 0, 0, 0]))[:3, 3], (0.12,) * 3)
        try:
            return next((m for m in np.arange(0.0, 0.1, 0.005)
                         if any(c.obstacle == "probe_box" for c in world.contacts(m))), 1.0)
        finally:
            world.remove_obstacle("probe_box")

    near = next(dq for dq in np.arange(0.01, 0.6, 0.01) if 0.0 < gap(dq) <= 0.02)    # 5-20 mm from the arm
    assert not place(0.0)       # the box would stand around the arm: not placed
    assert not place(near)      # a hair from it: not placed either
    assert place(0.8)           # well ahead of the arm: placed
    assert "obstacle_t" not in world.obstacles


def test_an_obstacle_against_the_stopped_arm_is_found_by_a_test_that_bumps_too(session, handler, arm):
    """A box put against the arm where it stands: the next measurement's first move bumps,
    and so does the first diagnosis test's; the cause is the obstacle at the arm (not
    'unresolved', which left every later move bumping until the run's alarm), a person
    removes it, and the measurement is made."""
    world = session.world
    first, second = (_first(session, "us_probe_1", "web_thickness", skip=k) for k in (30, 31))
    session.kb.once("world", "reset_world")
    world.faults = FaultSet()
    out = measure_one(session, first, arm["state"], "us_probe_1")
    assert out.status is MeasureStatus.MEASURED, out.reason
    arm["state"] = out.state
    world.add_obstacle("box_at_arm", world.tcp_pose(np.asarray(world.q, dtype=float))[:3, 3], (0.12, 0.12, 0.12))
    out = measure_one(session, second, arm["state"], "us_probe_1")
    assert out.status is MeasureStatus.NOT_DONE and "BUMP" in (out.reason or ""), out.reason
    handled = handler.handle(out)
    arm["state"] = handled.outcome.state
    assert handled.diagnosis.exception == "bump"
    assert handled.diagnosis.cause == "obstacle_at_arm", handled.diagnosis.summary
    assert [t.outcome for t in handled.diagnosis.tests][-1] == "bump"
    assert not world.obstacles
    assert handled.outcome.status is MeasureStatus.MEASURED, handled.outcome.reason


def test_a_test_that_shows_another_fault_still_answers_for_this_one(session, handler, arm, monkeypatch):
    """A controller time-out tested at the couplant station, which turns out empty: the
    empty station is another fault (no cause of a time-out predicts it); for these causes
    the station answered, so the controller does: a transient glitch, not 'no cause' (the
    one diagnosis of three campaign seeds that missed its injected cause)."""
    from ita.diagnosis.classify import Classified
    from ita.diagnosis.tests import Situation, TestRun

    spec_id = _first(session, "us_probe_1", "web_thickness", skip=3)
    situation = Situation(spec_id, "us_probe_1", "us_tool", "controller_timeout", arm["state"], device="controller")
    exc = Classified("controller_timeout", (("device", "controller"), ("probe", "us_probe_1"),
                                            ("tool", "us_probe_1")), "TIMEOUT(timeout)")
    monkeypatch.setattr(handler.bench, "cost", lambda name, s: 3.0 if name == "check_couplant_station" else None)
    monkeypatch.setattr(handler.bench, "run", lambda name, s, est: TestRun(name, "empty", est, 0.0, 1.0, s.state))
    runs, _, last = handler._diagnose(exc, situation, [], [], 0)
    assert [r.test for r in runs] == ["check_couplant_station"]
    assert runs[0].outcome == "ok" and "another fault" in runs[0].note
    assert last.choice == ("isolated", "transient_glitch")
