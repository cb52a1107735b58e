"""STOP and INTERRUPT for a running inspection: Ctrl-C from the terminal, and the archive's
control table from `ita monitor`.

    with RunSignals() as signals:          # Ctrl-C once: INTERRUPT; twice: STOP (raises StopNow)
        ...
        if signals.interrupt: ...          # finish the current plan, save, leave
        signals.poll(archive, run_id)      # take STOP / INTERRUPT issued by `ita monitor`

INTERRUPT: the current measurement's plan runs to its end and its result is recorded,
then the run stops, status INTERRUPTED.  STOP: halt at once: :class:`StopNow` is raised
where the program is (a half-done measurement leaves nothing in the archive: its result
and events are written in one transaction, or not at all), status STOPPED.  SIGTERM is a
STOP too.  A STOP from the control table is obeyed at the next poll (between
measurements, or between the commands of a plan).
"""

from __future__ import annotations

import signal
import sys
import threading
import time
from collections.abc import Callable
from types import FrameType
from typing import TYPE_CHECKING, TextIO

if TYPE_CHECKING:
    from ita.archive import Archive

__all__ = ["RunSignals", "StopNow"]


class StopNow(BaseException):
    """Raised to halt a run at once (a BaseException: no `except Exception` swallows it)."""


class RunSignals:
    """The run's STOP / INTERRUPT flags, set by signals or by the control table.

    message: where to print the notes for people (stderr by default; None: silent).
    poll_interval: least wall-clock seconds between two reads of the control table.
    """

    def __init__(self, *, message: TextIO | None = sys.stderr, poll_interval: float = 0.5) -> None:
        self.interrupt = False
        self.stop = False
        self.reason = ""
        self.message = message
        self.poll_interval = poll_interval
        self._last_poll = 0.0
        self._saved: dict[int, Callable[[int, FrameType | None], object] | int | None] = {}

    # -- signals ---------------------------------------------------------------------
    def __enter__(self) -> RunSignals:
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._saved[sig] = signal.signal(sig, self._handle)
        return self

    def __exit__(self, *exc: object) -> None:
        for sig, handler in self._saved.items():
            signal.signal(sig, handler)
        self._saved.clear()

    def _say(self, text: str) -> None:
        if self.message is not None:
            print(f"\n{text}", file=self.message, flush=True)

    def _handle(self, signum: int, _frame: FrameType | None) -> None:
        if signum == signal.SIGINT and not self.interrupt:
            self.interrupt = True
            self.reason = "Ctrl-C"
            self._say("INTERRUPT: finishing the current measurement, then saving (Ctrl-C again to STOP now)")
            return
        self.stop = True
        self.reason = "Ctrl-C twice" if signum == signal.SIGINT else "SIGTERM"
        self._say(f"STOP ({self.reason}): halting now")
        raise StopNow(self.reason)

    # -- the control table ---------------------------------------------------------------
    def poll(self, archive: Archive, run_id: str, *, force: bool = False) -> None:
        """Take a STOP / INTERRUPT request of the run from the archive (at most every
        poll_interval s unless `force`); a STOP raises StopNow."""
        now = time.monotonic()
        if not force and now - self._last_poll < self.poll_interval:
            return
        self._last_poll = now
        request = archive.take_control(run_id)
        if request is None:
            return
        if request.command.value == "STOP":
            self.stop = True
            self.reason = "STOP from the System Monitor"
            self._say(f"{self.reason}: halting now")
            raise StopNow(self.reason)
        if not self.interrupt:
            self.interrupt = True
            self.reason = "INTERRUPT from the System Monitor"
            self._say(f"{self.reason}: finishing the current measurement, then saving")
