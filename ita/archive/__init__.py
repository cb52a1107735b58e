"""The results archive: runs, results and events in an embedded SQLite database.

The Top Level creates or continues a run, records each result the moment it exists
(with the events that produced it, in one transaction), records events as they happen,
and polls for STOP / INTERRUPT from the System Monitor.  `ita runs`, `ita results` and
`ita report` read it.  See `store` for the durability argument, `schema` for the
tables, `decision` for the ISO 14253-1 rule, `timeline` for how events become a Gantt
chart and a cycle-time breakdown, `frames` for how range frames are kept; `ita.report` makes the reports.
"""

from ita.archive.decision import Decision, decide
from ita.archive.frames import StoredFrame
from ita.archive.model import (
                               ControlCommand,
                               ControlRequest,
                               Event,
                               EventKind,
                               Outcome,
                               Result,
                               RunInfo,
                               RunStatus,
                               StoredResult,
                               Stream,
)
from ita.archive.schema import SCHEMA_VERSION, SchemaError
from ita.archive.store import (
                               Archive,
                               ArchiveError,
                               NoArchive,
                               RunBusy,
                               UnknownRun,
                               archive_path,
                               new_run_id,
                               runs_dir,
)

__all__ = [
                               "SCHEMA_VERSION",
                               "Archive",
                               "ArchiveError",
                               "ControlCommand",
                               "ControlRequest",
                               "Decision",
                               "Event",
                               "EventKind",
                               "NoArchive",
                               "Outcome",
                               "Result",
                               "RunBusy",
                               "RunInfo",
                               "RunStatus",
                               "SchemaError",
                               "StoredFrame",
                               "StoredResult",
                               "Stream",
                               "UnknownRun",
                               "archive_path",
                               "decide",
                               "new_run_id",
                               "runs_dir",
]
