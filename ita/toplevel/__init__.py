"""The Top Level: runs an inspection at the sequence level (seed, "Top Level").

    from ita.task import open_session
    from ita.toplevel import start_run, TopLevel, RunSignals
    session = open_session(part_dir, seed=1)          # KBs, part, plan, MKB, simulator, devices
    with RunSignals() as signals:                     # Ctrl-C: INTERRUPT, twice: STOP
        run_id = start_run(session, archive, limit=12)
        summary = TopLevel(session, archive, run_id, signals).run(on_progress=print)

Modules: :mod:`~ita.toplevel.loop` (the sequence-level loop), :mod:`~ita.toplevel.events`
(a plan's log as archive events), :mod:`~ita.toplevel.signals` (STOP and INTERRUPT).
Each measurement's round trip is the task level's (:mod:`ita.task`), shared with `ita
measure` and the Exception Handler (:mod:`ita.diagnosis`) below this level.
"""

from ita.toplevel.events import archive_events
from ita.toplevel.loop import Progress, RunSummary, TopLevel, start_run
from ita.toplevel.signals import RunSignals, StopNow

__all__ = [
    "Progress",
    "RunSignals",
    "RunSummary",
    "StopNow",
    "TopLevel",
    "archive_events",
    "start_run",
]
