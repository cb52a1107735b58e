"""Runs started from the System Monitor: `ita inspect` / `ita continue` as child processes
on the same runs directory, their output in a log file beside the archive.

    procs = Processes(runs_dir)
    run_id = procs.start_inspect(limit=40, seed=0, part=None)
    procs.continue_run(run_id)
    procs.log_tail(run_id)

The child is the command line itself (`python -m ita.cli ...`), so a run started here
is the same as one started in a terminal: STOP and INTERRUPT reach it through the
archive's control table, and it may outlive the server (it is in a session of its own:
the server's Ctrl-C does not reach it).  While the server runs, each child has a thread
that waits for it, so one that ends is reaped at once and never left a zombie.
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading
from dataclasses import dataclass, field
from pathlib import Path

from ita.archive import new_run_id

LOG_DIR = "monitor-logs"


#: seconds a new child for a run waits for the run's previous one to finish closing
EXIT_WAIT_S = 60.0


@dataclass(eq=False)
class Processes:
    """The child processes this server started (reaped as they end), by run id."""

    runs_dir: Path
    python: str = sys.executable
    _children: dict[str, subprocess.Popen] = field(default_factory=dict)
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def log_path(self, run_id: str) -> Path:
        return Path(self.runs_dir) / LOG_DIR / f"{run_id}.log"

    def _watch(self, child: subprocess.Popen) -> None:
        """Reap `child` the moment it ends (a daemon thread blocked in its wait: no
        SIGCHLD handler, no polling; it goes with the server, the child does not)."""
        threading.Thread(target=child.wait, name=f"reap-{child.pid}", daemon=True).start()

    def _spawn(self, run_id: str, args: list[str]) -> None:
        log = self.log_path(run_id)
        log.parent.mkdir(parents=True, exist_ok=True)
        with self._lock:
            self._reap()
            old = self._children.get(run_id)
            if old is not None and old.poll() is None:
                try:                  # a stopped run's process may still be saving and closing: let it
                    old.wait(timeout=EXIT_WAIT_S)
                except subprocess.TimeoutExpired:
                    raise RuntimeError(f"run {run_id} already has a process of this server (pid {old.pid})") from None
            with open(log, "ab") as out:
                child = subprocess.Popen(
                    [self.python, "-m", "ita.cli", *args, "--runs-dir", str(self.runs_dir)],
                    stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT,
                    env=dict(os.environ, PYTHONUNBUFFERED="1"), start_new_session=True)
            self._children[run_id] = child
            self._watch(child)

    def start_inspect(self, *, limit: int | None = None, seed: int = 0, part: str | None = None,
                      faults: float = 0.0, serial: str | None = None, operator: str | None = None,
                      inject: tuple[str, ...] = ()) -> str:
        """Start `ita inspect` for a new run; returns its id (the run appears in the
        archive once the child has loaded the system, about a minute)."""
        run_id = new_run_id()
        args = ["inspect", "--run-id", run_id, "--seed", str(int(seed))]
        if limit is not None:
            args += ["--limit", str(int(limit))]
        if faults:
            args += ["--faults", repr(float(faults))]
        for script in inject:
            args += ["--inject", script]
        if part:
            args += ["--part", part]
        if serial:
            args += ["--serial", serial]
        if operator:
            args += ["--operator", operator]
        self._spawn(run_id, args)
        return run_id

    def continue_run(self, run_id: str) -> None:
        """Start `ita continue RUN`."""
        self._spawn(run_id, ["continue", run_id])

    def running(self, run_id: str) -> bool:
        """Whether this server's child for `run_id` still runs."""
        with self._lock:
            p = self._children.get(run_id)
            return p is not None and p.poll() is None

    def pid(self, run_id: str) -> int | None:
        """The process id of this server's (last) child for `run_id`; None when none."""
        with self._lock:
            p = self._children.get(run_id)
            return None if p is None else p.pid

    def exit_code(self, run_id: str) -> int | None:
        with self._lock:
            p = self._children.get(run_id)
            return None if p is None else p.poll()

    def log_tail(self, run_id: str, chars: int = 3000) -> str:
        """The end of the child's output (progress lines, errors); "" when none."""
        log = self.log_path(run_id)
        if not log.is_file():
            return ""
        with open(log, "rb") as f:
            f.seek(max(0, log.stat().st_size - chars))
            text = f.read().decode("utf-8", "replace")
        return text.replace("\r", "\n")

    def _reap(self) -> None:
        for p in self._children.values():
            p.poll()

    def close(self, timeout: float = 0.0) -> None:
        """Reap finished children; running ones are left to finish (they are runs)."""
        with self._lock:
            self._reap()
