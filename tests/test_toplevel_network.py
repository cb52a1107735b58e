"""Hole positions decided by the network of a run's frames (ita.toplevel.network): pending
until the network is solved, and a run killed before that loses and repeats nothing."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from collections import Counter
from pathlib import Path

from archive_synth import wait_for_run

from ita.archive import Archive, Event, archive_path
from ita.toplevel.network import EVENT_KIND, Pending
from ita.vision.network import Sighting

REPO = Path(__file__).resolve().parent.parent


def test_a_pending_frame_survives_the_archive() -> None:
    p = Pending("HP-OF-001", "slra_1", 1.0, 2.5, (Sighting("HP-OF-001", "OF-001", (28.9, -732.0), 0.01, 0.002),
                                                   Sighting("HP-OF-001", "OF-002", (86.7, -732.1), 0.03, 0.0, "half rim")),
                0.21, 0.05)
    again = Pending.from_event(Event(EVENT_KIND, "top", 2.5, p.to_event().payload))
    assert again == p


def test_killed_before_its_network_is_solved_continue_loses_and_repeats_nothing(tmp_path, ita_home,
                                                                                builtin_part) -> None:
    runs = tmp_path / "runs"
    env = dict(os.environ, PYTHONPATH=str(REPO), ITA_HOME=str(ita_home))
    # the first 12 fastener-hole positions (decided by a network) of the SLRA group, in the
    # plan's order (the probe's group comes first), as `ita inspect --network` would run them
    child = f"""
from ita.archive import Archive, archive_path
from ita.toplevel import RunSignals, TopLevel
from ita.task import open_session
session = open_session(None, seed=4)
ids = [i for i in next(g for g in session.plan.groups if g.tool.startswith("slra")).order
       if i.startswith("HP-IF")][:12]
with Archive.open(archive_path({str(runs)!r})) as archive:
    run_id = archive.create_run("bulkhead", session.part.directory, seed=4, total=len(ids),
                                settings={{"specs": ids, "network": True, "simulated": True}})
    TopLevel(session, archive, run_id, RunSignals(message=None)).run()
"""
    cmd = [sys.executable, "-c", child]
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:   # kill it once two position frames wait for their network
        run_id = wait_for_run(proc, runs, lambda a, r: len(a.events(r, kinds=[EVENT_KIND])) >= 2)
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(timeout=30)
    assert run_id is not None, "no position frame was kept pending"
    with Archive.open(archive_path(runs)) as archive:
        pending = {e.payload["spec"] for e in archive.events(run_id, kinds=[EVENT_KIND])}
        assert archive.run(run_id).state_label == "dead"
        assert not pending & archive.done_spec_ids(run_id)        # not decided before the network is solved
        # and nothing of theirs lost: their range frames and details are in the archive already
        assert all(archive.frames(run_id, s) and archive.details(run_id, s) for s in pending)
    done = subprocess.run([sys.executable, str(REPO / "cli.py"), "continue", run_id, "--runs-dir", str(runs)],
                          env=env, capture_output=True, text=True, timeout=400, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    with Archive.open(archive_path(runs)) as archive:
        results = archive.results(run_id)
        ids = Counter(r.spec_id for r in results)
        assert ids.keys() == set(archive.run(run_id).settings["specs"]) and set(ids.values()) == {1}
        positions = {r.spec_id: r for r in results if r.spec_id.startswith("HP-")}
        assert pending <= positions.keys()
        # each position was measured once (its frame kept across the kill), decided by the network
        plans = Counter(e.payload.get("spec") for e in archive.events(run_id, kinds=["plan_start"]))
        frames = Counter(e.payload["spec"] for e in archive.events(run_id, kinds=[EVENT_KIND]))
        assert all(plans[i] == 1 and frames[i] == 1 for i in positions), {i: (plans[i], frames[i]) for i in positions}
        assert all(r.outcome.value == "measured" and "network of" in (r.reason or "")
                   for r in positions.values()), [r.reason for r in positions.values()]
        assert len(archive.events(run_id, kinds=["network"])) >= 1, archive.events(run_id, kinds=["network"])
        assert all(archive.frames(run_id, s) for s in pending)


def test_an_uncertain_result_says_why() -> None:
    from types import SimpleNamespace

    from ita.archive import Result
    from ita.specs.model import MeasurementKind as K
    from ita.toplevel.recording import why_uncertain

    spec = SimpleNamespace(id="HD-OF-001", kind=K.HOLE_DIAMETER, point=(0.0, 0.0, 45.0), nominal=6.35,
                           lower=-0.076, upper=0.076)
    source = SimpleNamespace(diagnostics={"budget": {"rim fit": 0.004, "edge model": 0.011}})
    near_limit = why_uncertain(Result.measured(spec, 6.42, 0.011, reason="from the frame of X"),
                               SimpleNamespace(source=source))
    assert near_limit.decision.value == "uncertain"
    assert near_limit.reason == "from the frame of X; U/tolerance 0.14; largest term: edge model (u 0.0110 mm)"
    inside = Result.measured(spec, 6.35, 0.011)
    assert why_uncertain(inside, SimpleNamespace(source=source)) is inside


def test_positions_held_since_the_cell_was_found_off_are_let_go_and_stay_gone_after_a_kill(tmp_path) -> None:
    """The arm or the part found off: the positions held for their networks whose frames
    were taken since the last good check are let go (measured again), the older ones kept;
    a run continued after a kill does not hold the ones let go again (the ``remeasure``
    event names them), but holds a frame measured again after it."""
    from types import SimpleNamespace

    from ita.toplevel.pending import HeldPositions

    session = SimpleNamespace(slra=SimpleNamespace(vctx=SimpleNamespace(features={})), specs={})
    sighting = (Sighting("x", "OF-001", (28.9, -732.0), 0.01, 0.002),)
    with Archive.open(tmp_path / "archive.sqlite") as archive:
        run_id = archive.create_run("bulkhead")
        for k, spec in enumerate(("HP-1", "HP-2", "HP-3")):
            archive.record_event(run_id, Pending(spec, "slra_1", 10.0 * k, 10.0 * k + 2, sighting, 0.2, 0.05).to_event())

        def held() -> HeldPositions:
            return HeldPositions.resume(session, archive, run_id, SimpleNamespace(done=set()), [],  # type: ignore[arg-type]
                                        network=True)

        positions = held()
        assert sorted(positions.pending) == ["HP-1", "HP-2", "HP-3"]
        assert sorted(positions.release(12.0)) == ["HP-2", "HP-3"] and list(positions.pending) == ["HP-1"]
        archive.record_event(run_id, Event("remeasure", "top", 30.0, {"cause": "part_displaced",
                                                                      "released": ["HP-2", "HP-3"]}))
        assert list(held().pending) == ["HP-1"]                      # killed now: not held again
        archive.record_event(run_id, Pending("HP-3", "slra_1", 40.0, 42.0, sighting, 0.2, 0.05).to_event())
        assert sorted(held().pending) == ["HP-1", "HP-3"]            # measured again after: held
