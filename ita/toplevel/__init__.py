"""The Top Level: runs an inspection at the sequence level (seed, "Top Level").

    from ita.toplevel import open_session, start_run, TopLevel, RunSignals
    session = open_session(part_dir, seed=1)          # KBs, part, plan, MKB, simulator, devices
    with RunSignals() as signals:                     # Ctrl-C: INTERRUPT, twice: STOP
        run_id = start_run(session, archive, limit=12)
        summary = TopLevel(session, archive, run_id, signals).run(on_progress=print)

Modules: :mod:`~ita.toplevel.session` (the loaded system), :mod:`~ita.toplevel.measure`
(one measurement's round trip, shared with `ita measure`), :mod:`~ita.toplevel.loop`
(the sequence-level loop), :mod:`~ita.toplevel.events` (a plan's log as archive
events), :mod:`~ita.toplevel.signals` (STOP and INTERRUPT).  The devices the executive
drives are :mod:`ita.devices`.
"""

from ita.toplevel.events import archive_events
from ita.toplevel.loop import Progress, RunSummary, TopLevel, start_run
from ita.toplevel.measure import MeasureOutcome, MeasureStatus, measure_one, state_after
from ita.toplevel.session import Session, open_session
from ita.toplevel.signals import RunSignals, StopNow

__all__ = [
    "MeasureOutcome",
    "MeasureStatus",
    "Progress",
    "RunSignals",
    "RunSummary",
    "Session",
    "StopNow",
    "TopLevel",
    "archive_events",
    "measure_one",
    "open_session",
    "start_run",
    "state_after",
]
