"""User goals (`ita kb query`, `kb why`, `kb shell`) run in a child process with walls.

The main ITA process never runs a goal a person typed.  :func:`run_user_goal` starts
``swipl`` on ``prolog/kb_sandbox.pl`` behind the operating system's walls of
:mod:`ita.logic.confine`: bubblewrap's namespaces (a file system of SWI-Prolog and the
project's ``prolog/`` and ``kb/`` only, read-only; no network; a PID namespace that dies
with it; ``nobody`` with no capability), a seccomp filter (no process, thread, program,
socket or file write), and limits set before it starts:

- ``RLIMIT_CPU``: the time limit plus the start-up allowance, so a goal that swallows
  every Prolog limit still cannot burn a core;
- ``RLIMIT_AS``: the address space (1 GiB by default), so memory of a query is capped;
- ``RLIMIT_FSIZE`` 0: the child cannot write a byte to any file;
- ``RLIMIT_NOFILE``: few open files; ``RLIMIT_CORE`` 0: no core dumps;
- when ITA runs as root: the child becomes the user ``nobody`` before bwrap starts
  (when nobody can read every Prolog file it loads);

and Prolog's own stack limit, so a deeply nested term raises a resource error rather
than crashing.  The parent enforces a wall-clock limit: once the child says it is ready
(the knowledge bases are loaded), the goal has its time limit plus one second of grace,
after which bwrap is killed, and the kernel kills everything in its PID namespace.
Ctrl-C kills the child and raises KeyboardInterrupt in the parent.  Inside the child the
goal still goes through goal_hazard/2 and library(sandbox) (prolog/kb_query.pl) before
it runs: those checks give the clear refusals; the walls hold when they are wrong.

Refusals and limits come back as :class:`~ita.errors.QueryRefused` and
:class:`~ita.errors.QueryLimitExceeded`, a goal's own error as
:class:`~ita.errors.PrologError`, each with a one-line reason; a machine that cannot
raise the walls gives :class:`~ita.logic.confine.Unconfinable` and runs no goal.
"""

from __future__ import annotations

import json
import os
import selectors
import signal
import subprocess
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ita.errors import (
    ItaError,
    KBLoadError,
    Location,
    PrologError,
    QueryLimitExceeded,
    QueryRefused,
)
from ita.logic.confine import (
    Jail,
    RLimits,
    Unconfinable,
    await_namespace_end,
    namespace_pid,
)
from ita.logic.model import ProofNode, QueryResult
from ita.paths import resource_dir

__all__ = ["SandboxLimits", "SandboxFiles", "run_user_goal", "query", "explain", "Unconfinable"]

# The engine modules the sandbox does not offer to user goals (the bridge's own).
BRIDGE_MODULES = ("py_bridge", "kb_query", "kb_explain", "kb_check", "kb_sandbox")


@dataclass(frozen=True)
class SandboxLimits:
    """The limits of one user goal.

    `time_limit` (s, wall clock from the moment the knowledge bases are loaded) and
    `inference_limit` are the user's; the others are the process's walls.
    """

    time_limit: float = 10.0
    inference_limit: int = 10_000_000
    memory_bytes: int = 1 << 30          # RLIMIT_AS of the child
    stack_bytes: int = 256 << 20         # Prolog's stack_limit (all stacks together)
    open_files: int = 64                 # RLIMIT_NOFILE
    grace: float = 1.0                   # wall clock past time_limit before the kill
    load_seconds: float = 60.0           # wall clock allowed for loading the KBs
    output_bytes: int = 1 << 20          # what the goal may print, per stream
    reply_bytes: int = 64 << 20          # the largest reply read

    def __post_init__(self) -> None:
        if not (self.time_limit > 0 and self.inference_limit > 0):
            raise QueryRefused("limits must be positive")


@dataclass(frozen=True)
class SandboxFiles:
    """The Prolog files the child loads: engines (prolog/) then knowledge bases (kb/).

    `entry_file` is the file ``swipl`` starts on, whose ``kb_sandbox:sandbox_main/0``
    answers the request (default: ``kb_sandbox.pl`` among the engine files)."""

    engine_files: tuple[Path, ...]
    kb_files: tuple[Path, ...]
    entry_file: Path | None = field(default=None)

    @staticmethod
    def of(prolog_dir: Path | None = None, kb_dir: Path | None = None) -> "SandboxFiles":
        prolog_dir = Path(prolog_dir) if prolog_dir else resource_dir("prolog")
        kb_dir = Path(kb_dir) if kb_dir else resource_dir("kb")
        return SandboxFiles(_pl_files(prolog_dir), _pl_files(kb_dir))

    @property
    def entry(self) -> Path:
        """The file the child starts on."""
        if self.entry_file is not None:
            return Path(self.entry_file).resolve()
        for path in self.engine_files:
            if path.name == "kb_sandbox.pl":
                return path
        return (resource_dir("prolog") / "kb_sandbox.pl").resolve()

    @property
    def all_files(self) -> tuple[Path, ...]:
        """Every file the child reads: the entry, the engines, the knowledge bases."""
        return (self.entry, *self.engine_files, *self.kb_files)

    def jail(self) -> Jail:
        """The walls of a child that reads these files (their directories, read-only).

        Raises Unconfinable when this machine cannot raise them."""
        directories = {path.parent for path in self.all_files}
        return Jail.find("swipl", sorted(directories), self.all_files)


@dataclass(frozen=True)
class Outcome:
    """What a child said, and what the goal printed (its standard error)."""

    reply: dict[str, Any]
    printed: str


def _pl_files(directory: Path) -> tuple[Path, ...]:
    return tuple(sorted(p.resolve() for p in directory.glob("*.pl") if p.is_file()))


def query(goal: str, files: SandboxFiles, limits: SandboxLimits, limit: int = 100,
          echo: Callable[[str], None] | None = None, jail: Jail | None = None) -> QueryResult:
    """All solutions (at most `limit`) of the user goal `goal`, run in a child process.

    `echo` receives whatever the goal printed (default: dropped); `jail` are the walls
    (default: found for `files`; pass one to reuse it across goals)."""
    outcome = run_user_goal("query", goal, files, limits, {"limit": int(limit)}, jail)
    _echo(outcome, echo)
    reply = outcome.reply
    if reply.get("status") != "answers":
        raise PrologError(goal, f"unexpected reply from the query process: {reply.get('status')!r}")
    return QueryResult(
        goal=goal,
        variables=tuple(str(v) for v in reply["variables"]),
        rows=tuple(tuple(str(v) for v in row) for row in reply["rows"]),
        truncated=bool(reply["truncated"]),
    )


def explain(goal: str, files: SandboxFiles, limits: SandboxLimits, max_depth: int = 30,
            echo: Callable[[str], None] | None = None, jail: Jail | None = None) -> ProofNode | None:
    """The proof tree of the first solution of the user goal, or None without one."""
    outcome = run_user_goal("why", goal, files, limits, {"max_depth": int(max_depth)}, jail)
    _echo(outcome, echo)
    reply = outcome.reply
    if reply.get("status") == "no_proof":
        return None
    if reply.get("status") != "proof":
        raise PrologError(goal, f"unexpected reply from the query process: {reply.get('status')!r}")
    return _node(reply["tree"])


def _echo(outcome: Outcome, echo: Callable[[str], None] | None) -> None:
    if echo is not None and outcome.printed:
        echo(outcome.printed)


def _node(data: dict[str, Any]) -> ProofNode:
    file, line = str(data["file"]), int(data["line"])
    return ProofNode(
        goal=str(data["goal"]),
        kind=str(data["kind"]),
        location=Location(file, line) if file else None,
        children=tuple(_node(c) for c in data["children"]),
    )


def _check_text(goal: str) -> bytes:
    try:
        return goal.encode("utf-8")
    except UnicodeEncodeError as exc:
        raise QueryRefused(
            f"refused: the goal is not valid UTF-8 text (byte {exc.object[exc.start:exc.end]!r} "
            f"at character {exc.start})"
        ) from None


def run_user_goal(action: str, goal: str, files: SandboxFiles, limits: SandboxLimits,
                  extra: Mapping[str, int], jail: Jail | None = None) -> Outcome:
    """Run `goal` (action ``query`` or ``why``) in a child ``swipl`` behind `jail`'s
    walls (default: ``files.jail()``); its reply.

    Raises QueryRefused, QueryLimitExceeded, PrologError or KBLoadError for every
    reply or end of the child that is not an answer, Unconfinable when the walls
    cannot be raised (the goal does not run).
    """
    _check_text(goal)
    if jail is None:
        jail = files.jail()
    request = {
        "action": action,
        "goal": goal,
        "engine_files": [jail.inside(p) for p in files.engine_files],
        "kb_files": [jail.inside(p) for p in files.kb_files],
        "bridge_modules": list(BRIDGE_MODULES),
        "limit": 100,
        "max_depth": 30,
        "inference_limit": int(limits.inference_limit),
        **extra,
    }
    stack = max(1, limits.stack_bytes >> 20)
    args = ["-q", "-f", "none", "--no-packs", "--no-tty", f"--stack-limit={stack}m",
            "-g", "kb_sandbox:sandbox_main", "-t", "halt(4)", jail.inside(files.entry)]
    env = {"LANG": "C.UTF-8", "LC_ALL": "C.UTF-8", "HOME": "/nonexistent"}
    cpu = int(limits.load_seconds + limits.time_limit + limits.grace) + 1
    seccomp = jail.seccomp_pipe()
    info, info_w = os.pipe()
    command = jail.command(args, seccomp, env, info_w)
    try:
        child = subprocess.Popen(
            command, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
            start_new_session=True, pass_fds=(seccomp, info_w),
            preexec_fn=jail.preexec(RLimits(cpu, limits.memory_bytes, limits.open_files)),
            cwd="/", env=env,
        )
    except (OSError, subprocess.SubprocessError) as exc:
        os.close(info)
        raise ItaError(f"cannot start the query process ({command[0]}): {exc}") from None
    finally:
        os.close(seccomp)
        os.close(info_w)
    confined = _Confined(child, info)
    try:
        outcome = _converse(confined, request, limits)
    except ItaError as exc:
        raise _outside(exc, jail) from None
    finally:
        confined.stop()
    return Outcome(_outside_json(outcome.reply, jail), jail.outside(outcome.printed))


class _Confined:
    """A started child: bwrap's process, and the pipe where bwrap writes the PID of its
    namespace's first process (``--info-fd``)."""

    def __init__(self, process: subprocess.Popen[bytes], info_fd: int) -> None:
        self.process = process
        self._info_fd = info_fd
        self._info = b""

    def _read_info(self) -> bytes:
        if self._info_fd >= 0:
            try:
                os.set_blocking(self._info_fd, False)
                self._info = os.read(self._info_fd, 4096)
            except OSError:
                pass
            finally:
                os.close(self._info_fd)
                self._info_fd = -1
        return self._info

    def stop(self) -> None:
        """End the child and everything in its PID namespace, and reap it.

        While bwrap still runs, the namespace's first process is killed first, so that
        the kernel kills the rest and bwrap reaps it and exits on its own (killing bwrap
        first would leave that process to whoever adopts orphans); then bwrap's process
        group; then this waits until the namespace is gone."""
        child = self.process
        info = self._read_info()
        if child.poll() is None:
            pid = namespace_pid(info)
            if pid is not None:
                try:
                    os.kill(pid, signal.SIGKILL)  # bwrap has not reaped it: the PID is still its
                except (ProcessLookupError, PermissionError):
                    pass
            try:
                child.wait(timeout=2.0)
            except subprocess.TimeoutExpired:
                pass
        try:
            os.killpg(child.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
        child.wait()
        await_namespace_end(info)
        for stream in (child.stdin, child.stdout, child.stderr):
            if stream is not None:
                try:
                    stream.close()
                except OSError:
                    pass


def _converse(confined: _Confined, request: dict[str, Any], limits: SandboxLimits) -> Outcome:
    """Send the request, collect output and reply under the wall-clock limits."""
    child = confined.process
    assert child.stdin is not None and child.stdout is not None and child.stderr is not None
    try:
        child.stdin.write(json.dumps(request).encode("utf-8") + b"\n")
        child.stdin.close()
    except BrokenPipeError:
        pass
    reply_fd, err_fd = child.stdout.fileno(), child.stderr.fileno()
    buffers: dict[int, bytearray] = {err_fd: bytearray(), reply_fd: bytearray()}
    caps = {err_fd: limits.output_bytes, reply_fd: limits.reply_bytes}
    selector = selectors.DefaultSelector()
    for fd in buffers:
        os.set_blocking(fd, False)
        selector.register(fd, selectors.EVENT_READ)
    started = time.monotonic()
    deadline = started + limits.load_seconds
    ready_at: float | None = None
    killed_for: str | None = None
    try:
        while selector.get_map():
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                killed_for = "time" if ready_at is not None else "load"
                break
            for key, _ in selector.select(timeout=min(remaining, 0.5)):
                fd = key.fd
                try:
                    data = os.read(fd, 65536)
                except BlockingIOError:
                    continue
                if not data:
                    selector.unregister(fd)
                    continue
                buffer = buffers[fd]
                if len(buffer) < caps[fd]:
                    buffer += data[: caps[fd] - len(buffer)]
                elif fd == reply_fd:
                    killed_for = "reply"
                if ready_at is None and fd == reply_fd and b"\n" in buffer:
                    ready_at = time.monotonic()
                    deadline = ready_at + limits.time_limit + limits.grace
            if killed_for:
                break
    except KeyboardInterrupt:
        confined.stop()
        raise
    finally:
        selector.close()
    if killed_for is None:
        try:
            child.wait(timeout=max(0.1, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            killed_for = "time"
    confined.stop()
    printed = buffers[err_fd].decode("utf-8", "replace")
    reply_lines = buffers[reply_fd].decode("utf-8", "replace").splitlines()
    if killed_for is None and len(reply_lines) >= 2 and reply_lines[0] == "ready":
        try:
            reply = json.loads(reply_lines[1])
        except (ValueError, RecursionError):
            raise PrologError(request["goal"], "the query process sent a reply that cannot be read") from None
        _raise_for(reply, request["goal"])
        return Outcome(reply, printed)
    raise _ended(child.returncode, killed_for, limits, printed, request["goal"])


def _raise_for(reply: dict[str, Any], goal: str) -> None:
    status, reason = reply.get("status"), str(reply.get("reason", ""))
    if status == "refused":
        raise QueryRefused(reason)
    if status == "limit_exceeded":
        raise QueryLimitExceeded(reason)
    if status == "error":
        raise PrologError(goal, reason)
    if status == "load_error":
        raise KBLoadError([(Location(reason.split(":", 1)[0]), reason)])


def _ended(code: int | None, killed_for: str | None, limits: SandboxLimits, stderr: str,
           goal: str) -> ItaError:
    """The error for a child that ended without a reply."""
    if killed_for == "time":
        return QueryLimitExceeded(
            f"stopped: the goal ran longer than {limits.time_limit:g} s (time limit); "
            "its process was killed")
    if killed_for == "load":
        return QueryLimitExceeded(
            f"stopped: loading the knowledge bases took longer than {limits.load_seconds:g} s")
    if killed_for == "reply":
        return QueryLimitExceeded(
            f"stopped: the answer is larger than {limits.reply_bytes >> 20} MiB; narrow the goal "
            "or lower --limit")
    mib = limits.memory_bytes >> 20
    walls = _wall_failure(stderr)
    if walls is not None:
        return walls
    if code is not None and code < 0:
        sig = -code
        if sig == signal.SIGXCPU:
            return QueryLimitExceeded("stopped: the goal used up its CPU time (time limit); "
                                      "its process was killed")
        if sig == signal.SIGXFSZ:
            return QueryRefused("refused: the goal tried to write a file; its process was killed")
        if sig in (signal.SIGSEGV, signal.SIGBUS, signal.SIGABRT):
            return QueryLimitExceeded(
                f"stopped: the goal crashed its process ({signal.Signals(sig).name}), "
                f"most likely out of memory (limit {mib} MiB) or a term nested too deep")
        return QueryLimitExceeded(f"stopped: the query process was ended by {signal.Signals(sig).name}")
    lowered = stderr.lower()
    if "memory" in lowered or "resource" in lowered or "stack" in lowered:
        return QueryLimitExceeded(f"stopped: out of memory (limit {mib} MiB for a query)")
    last = next((line for line in reversed(stderr.splitlines()) if line.strip()), "")
    detail = f": {last.strip()[:200]}" if last else ""
    return PrologError(goal, f"the query process ended without an answer (exit {code}){detail}")


def _wall_failure(stderr: str) -> Unconfinable | None:
    """The error for a bwrap that could not raise its walls (it says ``bwrap: ...``)."""
    line = next((line.strip() for line in stderr.splitlines() if line.startswith("bwrap:")), None)
    if line is None:
        return None
    hint = ""
    if "namespace" in line.lower() or "uid map" in line.lower() or "permission" in line.lower():
        hint = ("; the kernel must allow unprivileged user namespaces (sysctl "
                "user.max_user_namespaces > 0, kernel.unprivileged_userns_clone=1, and no "
                "AppArmor restriction on them), or run ITA as root")
    return Unconfinable(f"cannot confine the query process ({line[:200]}){hint}; "
                        "no goal runs without its walls")


def _outside_json(value: Any, jail: Jail) -> Any:
    """A reply with the jail's paths written as they are outside (proof trees' files)."""
    if isinstance(value, str):
        return jail.outside(value)
    if isinstance(value, list):
        return [_outside_json(v, jail) for v in value]
    if isinstance(value, dict):
        return {k: _outside_json(v, jail) for k, v in value.items()}
    return value


def _outside(exc: ItaError, jail: Jail) -> ItaError:
    """The error with the jail's paths written as they are outside (a load error's file)."""
    if isinstance(exc, KBLoadError):
        return KBLoadError([(Location(jail.outside(loc.file), loc.line, loc.column, loc.field),
                             jail.outside(message)) for loc, message in exc.problems])
    if isinstance(exc, PrologError):
        return PrologError(exc.goal, jail.outside(exc.message))
    text = str(exc)
    fixed = jail.outside(text)
    if fixed == text:
        return exc
    try:
        return type(exc)(fixed)
    except TypeError:
        return exc
