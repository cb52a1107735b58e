"""The Top Level: runs an inspection at the sequence level (seed, "Top Level").

    from ita.toplevel import open_session, start_run, TopLevel, RunSignals
    session = open_session(part_dir, seed=1)          # KBs, part, plan, MKB, simulator, devices
    with RunSignals() as signals:                     # Ctrl-C: INTERRUPT, twice: STOP
        run_id = start_run(session, archive, limit=12)
        summary = TopLevel(session, archive, run_id, signals).run(on_progress=print)

Modules: :mod:`~ita.toplevel.loop` (session, the loop, events for the archive),
:mod:`~ita.toplevel.adapters` (the simulated arm with the gauge, and the SLRA with
Vision, as the Executive's device adapters), :mod:`~ita.toplevel.signals` (STOP and
INTERRUPT).
"""

from ita.toplevel.loop import (
    Progress,
    RunSummary,
    Session,
    TopLevel,
    archive_events,
    open_session,
    start_run,
    state_after,
)
from ita.toplevel.signals import RunSignals, StopNow

__all__ = [
    "Progress",
    "RunSignals",
    "RunSummary",
    "Session",
    "StopNow",
    "TopLevel",
    "archive_events",
    "open_session",
    "start_run",
    "state_after",
]
