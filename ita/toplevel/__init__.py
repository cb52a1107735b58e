"""The Top Level: runs an inspection at the sequence level (seed, "Top Level").

    from ita.task import open_session
    from ita.toplevel import start_run, TopLevel, RunSignals
    session = open_session(part_dir, seed=1)          # KBs, part, plan, MKB, simulator, devices
    with RunSignals() as signals:                     # Ctrl-C: INTERRUPT, twice: STOP
        run_id = start_run(session, archive, limit=12)
        summary = TopLevel(session, archive, run_id, signals).run(on_progress=print)

Modules: :mod:`~ita.toplevel.loop` (the run: its job of kb/tasks.pl planned by the HTN
planner, the plan's actions carried out), :mod:`~ita.toplevel.agenda` (an HTN plan being
carried out, planned again where an outcome differs),
:mod:`~ita.toplevel.start` (registering a run), :mod:`~ita.toplevel.progress` (the live
view's progress, the run's summary), :mod:`~ita.toplevel.recording` (results to the
archive, the failures-in-a-row alarm), :mod:`~ita.toplevel.pending` (results held for a
network of hole positions, :mod:`~ita.toplevel.network`, or for their webs' measured
thickness, :mod:`~ita.toplevel.heights`), :mod:`~ita.toplevel.calibration` (the probes on
the calibration block), :mod:`~ita.toplevel.handling` (the Exception Handler called on a
failure), :mod:`~ita.toplevel.events` (every archive event the Top Level builds),
:mod:`~ita.toplevel.details` (what is kept beside a result), :mod:`~ita.toplevel.signals`
(STOP and INTERRUPT).
Each measurement's round trip is the task level's (:mod:`ita.task`), shared with `ita
measure` and the Exception Handler (:mod:`ita.diagnosis`) below this level.
"""

from ita.toplevel.events import archive_events
from ita.toplevel.loop import TopLevel, job_tasks, jobs
from ita.toplevel.progress import Progress, RunSummary
from ita.toplevel.signals import RunSignals, StopNow
from ita.toplevel.start import earlier_results, start_run, tooling_specs, unproven

__all__ = [
    "Progress",
    "RunSignals",
    "RunSummary",
    "StopNow",
    "TopLevel",
    "archive_events",
    "earlier_results",
    "job_tasks",
    "jobs",
    "start_run",
    "tooling_specs",
    "unproven",
]
