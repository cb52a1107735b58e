"""Attacks on `ita kb query`, `kb why` and `kb shell`: every one refused or stopped
cleanly, with no side effect (no file, no changed fact in a later query, no process
left) and the exit code a user expects.

The attacks are listed in tests/kb_attacks.py (about 600, in nine groups).  The whole
list runs in the slow suite (and the family of issue 28, format directives built at run
time in thrown terms, through `kb why` and `kb shell` as well)::

    .venv/bin/python -m pytest -q -p no:cacheprovider -m slow tests/test_kb_attacks.py -s

which prints the table "group, cases tried, refused cleanly".  The default suite runs a
representative of each group end to end through the command line.

The arena the attacks aim at is world-writable (like /tmp), so that a goal that got out
could harm it whichever user the query child runs as; the walls alone are tested in
tests/test_kb_walls.py.
"""

from __future__ import annotations

import os
import shutil
import stat
import tempfile
import time
from collections import Counter
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest
from click.testing import CliRunner
from kb_attacks import GROUPS, Attack, all_attacks, thrown_formats

from ita.cli import main
from ita.errors import ItaError, QueryLimitExceeded, QueryRefused
from ita.logic.sandbox import SandboxFiles, SandboxLimits, explain, query

TIME_LIMIT = 1.0
SLACK = 2.0  # a limit holds within this many seconds of its setting
VICTIM = "victim.\n"
FACTS = "tool_condition(T, C)"
LEAKS = ("root:x:0:0", "root:*:0:0")  # /etc/passwd's first line, should a goal read it
ESCAPE = "X is 63+1, atom_codes(F, [126, X]), throw(format(F, [open('{t}/pwned', write, S)]))"


@pytest.fixture()
def arena() -> Iterator[Path]:
    """The test's own directory, world-writable like /tmp (so any user could harm it
    without the walls), under the system's temporary directory (reachable by every
    user), holding one world-writable file that attacks try to change or delete."""
    path = Path(tempfile.mkdtemp(prefix="ita-attacks-"))
    os.chmod(path, 0o1777)
    (path / "victim").write_text(VICTIM, encoding="utf-8")
    os.chmod(path / "victim", 0o666)
    yield path
    shutil.rmtree(path)


def assert_untouched(arena: Path) -> None:
    """No file made, changed or removed in the arena, and no process left behind."""
    assert sorted(p.name for p in arena.iterdir()) == ["victim"]
    assert (arena / "victim").read_text(encoding="utf-8") == VICTIM
    assert stat.S_IMODE((arena / "victim").stat().st_mode) == 0o666
    assert not _processes_mentioning(str(arena))
    assert not _swipl_children()


def _processes_mentioning(text: str) -> list[int]:
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            cmdline = (entry / "cmdline").read_bytes().decode("utf-8", "replace")
        except OSError:
            continue
        if text in cmdline:
            found.append(int(entry.name))
    return found


def _swipl_children() -> list[int]:
    """Our child processes running swipl or bwrap (the sandbox must reap every one)."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        name = stat[stat.index("(") + 1: stat.rindex(")")]
        ppid = int(stat[stat.rindex(")") + 2:].split()[1])
        if ppid == os.getpid() and (name.startswith("swipl") or name.startswith("bwrap")):
            found.append(int(entry.name))
    return found


# -- the default suite: one or more of each group, end to end -----------------------------

@pytest.fixture()
def ita(tmp_path: Path, monkeypatch):
    monkeypatch.setenv("ITA_HOME", str(tmp_path / "home"))
    runner = CliRunner()

    def invoke(*args: str, stdin: str | None = None):
        return runner.invoke(main, list(args), input=stdin)

    return invoke


def _error_line(output: str) -> str:
    lines = [line for line in output.splitlines() if line.startswith("error:")]
    assert len(lines) == 1, output
    return lines[0]


@pytest.fixture(scope="module")
def facts() -> tuple:
    """The tool conditions as a query sees them before any attack."""
    return query(FACTS, SandboxFiles.of(), SandboxLimits()).rows


def _facts_now() -> tuple:
    return query(FACTS, SandboxFiles.of(), SandboxLimits()).rows


REPRESENTATIVES = [
    ("side effects", "shell('touch {t}/pwned')", "refused"),
    ("side effects", "open('{t}/victim', write, S), close(S)", "refused"),
    ("escapes", "print_message(error, format('~@', [shell('touch {t}/pwned')]))", "refused"),
    ("escapes", "atom_concat('~', '@', F), print_message(error, format(F, [shell('touch {t}/pwned')]))",
     "refused"),
    ("escapes", "G = format('~@', [shell('touch {t}/pwned')]), print_message(error, G)", "refused"),
    ("escapes", "dif(X, a), put_attr(Y, freeze, shell('touch {t}/pwned')), Y = 1", "refused"),
    ("kb changes", "print_message(error, format('~@', [assertz(world:tool_condition(us_probe_2, broken))]))",
     "refused"),
    ("kb changes", "assertz(world:tool_condition(us_probe_2, broken))", "refused"),
    ("threads", "thread_create(set_tool_condition(us_probe_2, broken), _, [detached(true)])", "refused"),
    ("memory", "numlist(1, 100000000, L)", "stopped"),
    ("deep terms", "X = " + "f(" * 20_000 + "a" + ")" * 20_000, "clean"),
    ("deep terms", "length(L, 20000), foldl([_, A0, f(A0)]>>true, L, a, X)", "stopped"),
    ("encodings", "\udcff(X)", "clean"),  # refused by the ita group: not valid UTF-8
    ("encodings", "type(X, us_tool). shell('touch {t}/pwned')", "refused"),
    ("thrown formats", ESCAPE, "error"),
    ("thrown formats", "X is 63+1, atom_codes(F, [126, X]), "
     "throw(error(format(F, [read_file_to_string('/etc/passwd', S, [])]), _))", "error"),
    ("thrown formats", "atom_codes(F, [0'~, 0'@]), "
     "throw(error(foo, context(_, format(F, [shell('touch {t}/pwned')]))))", "error"),
]


@pytest.mark.parametrize("group,goal,expect", REPRESENTATIVES,
                         ids=[f"{g}-{i}" for i, (g, _, _) in enumerate(REPRESENTATIVES)])
def test_query_attack_is_refused_without_effect(ita, arena, facts, group, goal, expect):
    result = ita("kb", "query", goal.replace("{t}", str(arena)))
    assert result.exit_code == 2, result.output
    line = _error_line(result.output)
    if expect == "refused":
        assert line.startswith("error: refused:"), line
    elif expect == "stopped":
        assert line.startswith("error: stopped:"), line
    assert not any(leak in result.output for leak in LEAKS), result.output
    if "\udcff" in goal:
        assert "not valid UTF-8" in line
    assert "Traceback" not in result.output
    if group in ("kb changes", "threads"):
        assert _facts_now() == facts
    assert_untouched(arena)


@pytest.mark.parametrize("command", ["why", "shell"])
def test_why_and_shell_keep_the_thrown_format_escape_harmless(ita, arena, command):
    """The escape of issue 28 through `kb why` and `kb shell`: the thrown term is shown
    with ~q (the goal in it is data), nothing is made."""
    goal = ESCAPE.replace("{t}", str(arena))
    if command == "why":
        result = ita("kb", "why", goal)
        assert result.exit_code == 2, result.output
        line = _error_line(result.output)
    else:
        result = ita("kb", "shell", stdin=f"{goal}\ntype(X, arm)\n")
        assert result.exit_code == 0, result.output
        assert "t3" in result.output      # the shell goes on
        line = next(l for l in result.output.splitlines() if "unhandled exception" in l)
    assert "unhandled exception: format(" in line and "open(" in line, line
    assert "Traceback" not in result.output
    assert_untouched(arena)


def test_why_and_shell_refuse_the_message_escape(ita, arena):
    goal = f"print_message(error, format('~@', [shell('touch {arena}/pwned')]))"
    result = ita("kb", "why", goal)
    assert result.exit_code == 2 and _error_line(result.output).startswith("error: refused:")
    shell = ita("kb", "shell", stdin=f"{goal}\ntype(X, arm)\n")
    assert shell.exit_code == 0, shell.output
    assert "error: refused: print_message" in shell.output and "t3" in shell.output
    assert_untouched(arena)


@pytest.mark.parametrize("goal", ["sleep(1000)",
                                  "repeat, catch((between(1, inf, _), fail), _, true), fail"])
def test_limit_holds_within_two_seconds(ita, arena, goal):
    started = time.monotonic()
    ita("kb", "query", "true")
    startup = time.monotonic() - started
    started = time.monotonic()
    result = ita("kb", "query", goal, "--time-limit", str(TIME_LIMIT))
    elapsed = time.monotonic() - started
    assert result.exit_code == 2
    assert _error_line(result.output).startswith("error: stopped: the goal ran longer than 1 s")
    assert elapsed <= TIME_LIMIT + SLACK + startup, elapsed
    assert_untouched(arena)


def test_shell_flags_and_deep_input_do_not_leak(ita, arena):
    deep = "X = " + "[" * 20_000 + "]" * 20_000
    stdin = f'set_prolog_flag(double_quotes, atom)\nX = "ab", string(X)\n{deep}\ntype(X, arm)\n'
    result = ita("kb", "shell", stdin=stdin)
    assert result.exit_code == 0, result.output
    out = result.output
    assert "error: refused: set_prolog_flag" in out
    assert '"ab"' in out  # the next goal still reads "ab" as a string
    assert "t3" in out    # the shell survived the deep term
    assert_untouched(arena)


def test_shell_survives_a_line_that_is_not_utf8(arena, tmp_path):
    import subprocess
    import sys

    repo = Path(__file__).resolve().parent.parent
    env = dict(os.environ, PYTHONPATH=str(repo), ITA_HOME=str(tmp_path / "home"))
    proc = subprocess.run([sys.executable, str(repo / "cli.py"), "kb", "shell"],
                          input=b"\xff(X)\ntype(X, arm)\n", capture_output=True, env=env, timeout=120)
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout.decode("utf-8", "replace")
    assert "not valid UTF-8" in out and "t3" in out
    assert b"Traceback" not in proc.stderr
    assert_untouched(arena)


# -- the slow suite: every attack ----------------------------------------------------------

def _outcome(attack: Attack, arena: Path, files: SandboxFiles) -> tuple[Attack, str, str, float]:
    started = time.monotonic()
    try:
        result = query(attack.text(str(arena)), files, SandboxLimits(time_limit=TIME_LIMIT))
        kind, text = ("answer" if result.succeeded else "no answer"), repr(result.rows)[:2000]
    except QueryRefused as exc:
        kind, text = "refused", str(exc)
    except QueryLimitExceeded as exc:
        kind, text = "stopped", str(exc)
    except ItaError as exc:
        assert exc.exit_code == 2
        kind, text = "error", str(exc)
    return attack, kind, text, time.monotonic() - started


def _clean(attack: Attack, kind: str, text: str) -> bool:
    if any(leak in text for leak in LEAKS):
        return False
    if kind in ("refused", "stopped", "error"):
        if "\n" in text.strip() or not text.strip():
            return False
        if kind in ("refused", "stopped") and not text.startswith(kind + ":"):
            return False
    if "\x1b" in text or "\x07" in text:  # answers come back escaped, never raw
        return False
    return {
        "refused": kind == "refused",
        "stopped": kind == "stopped",
        "clean": kind in ("refused", "stopped", "error"),
        "harmless": True,
    }[attack.expect]


@pytest.mark.slow
def test_every_attack_is_refused_cleanly(arena, capsys):
    files = SandboxFiles.of()
    attacks = all_attacks()
    assert len(attacks) >= 194
    baseline = query(FACTS, files, SandboxLimits()).rows
    started = time.monotonic()
    query("true", files, SandboxLimits())
    startup = time.monotonic() - started
    with ThreadPoolExecutor(max_workers=2) as pool:
        outcomes = list(pool.map(lambda a: _outcome(a, arena, files), attacks))
    tried, clean = Counter(), Counter()
    failures = []
    for attack, kind, text, elapsed in outcomes:
        tried[attack.group] += 1
        ok = _clean(attack, kind, text)
        if kind == "stopped" and "time limit" in text:
            # two children at a time: allow for the other one's start-up as well
            ok = ok and elapsed <= TIME_LIMIT + SLACK + 2 * startup
        if ok:
            clean[attack.group] += 1
        else:
            failures.append(f"{attack.group}: {attack.goal[:80]!r} expected {attack.expect}, "
                            f"got {kind}: {text[:120]} ({elapsed:.1f} s)")
    with capsys.disabled():
        print("\n| category | cases tried | refused cleanly |\n|---|---|---|")
        for group in GROUPS:
            print(f"| {group} | {tried[group]} | {clean[group]} |")
        print(f"| total | {sum(tried.values())} | {sum(clean.values())} |")
    assert not failures, "\n".join(failures)
    assert query(FACTS, files, SandboxLimits()).rows == baseline
    assert_untouched(arena)


def _why_outcome(attack: Attack, arena: Path, files: SandboxFiles) -> tuple[Attack, str, str]:
    try:
        tree = explain(attack.text(str(arena)), files, SandboxLimits(time_limit=TIME_LIMIT))
        kind, text = "answer", repr(tree)[:2000]
    except QueryRefused as exc:
        kind, text = "refused", str(exc)
    except QueryLimitExceeded as exc:
        kind, text = "stopped", str(exc)
    except ItaError as exc:
        kind, text = "error", str(exc)
    return attack, kind, text


@pytest.mark.slow
def test_thrown_formats_through_why_and_shell(arena, ita, capsys):
    """Every attack of the thrown-formats family through `kb why` (each in its own
    child) and through one `kb shell` session: nothing made, nothing leaked."""
    files = SandboxFiles.of()
    attacks = thrown_formats()
    with ThreadPoolExecutor(max_workers=2) as pool:
        outcomes = list(pool.map(lambda a: _why_outcome(a, arena, files), attacks))
    failures = [f"why {a.goal[:80]!r}: {kind}: {text[:120]}" for a, kind, text in outcomes
                if not _clean(a, kind, text)]
    shell = ita("kb", "shell", stdin="".join(a.text(str(arena)) + "\n" for a in attacks) + "type(X, arm)\n")
    if shell.exit_code != 0 or "t3" not in shell.output or "Traceback" in shell.output:
        failures.append(f"shell: exit {shell.exit_code}: {shell.output[-500:]}")
    if any(leak in shell.output for leak in LEAKS):
        failures.append("shell: /etc/passwd leaked")
    with capsys.disabled():
        print(f"\n| thrown formats | why {len(attacks)} | shell {len(attacks)} | failures {len(failures)} |")
    assert not failures, "\n".join(failures)
    assert_untouched(arena)


def test_shell_lists_clauses_read_only(ita, arena):
    result = ita("kb", "shell", stdin="listing(available)\nlisting(shell)\n")
    assert result.exit_code == 0, result.output
    assert "available(A) :-" in result.output and "tool_condition(A, ok)" in result.output
    assert "error: refused: no knowledge-base predicate shell" in result.output
    assert_untouched(arena)


def test_ctrl_c_stops_the_goal_not_the_shell(arena, tmp_path):
    """On a terminal, Ctrl-C kills the running goal's process and the shell goes on."""
    import pty
    import select
    import signal
    import subprocess
    import sys

    repo = Path(__file__).resolve().parent.parent
    env = dict(os.environ, PYTHONPATH=str(repo), ITA_HOME=str(tmp_path / "home"))
    primary, secondary = pty.openpty()
    proc = subprocess.Popen([sys.executable, str(repo / "cli.py"), "kb", "shell"], stdin=secondary,
                            stdout=secondary, stderr=secondary, env=env, start_new_session=True)
    os.close(secondary)
    seen = b""

    def read_until(marker: bytes, timeout: float) -> bytes:
        nonlocal seen
        deadline = time.monotonic() + timeout
        while marker not in seen and time.monotonic() < deadline:
            ready, _, _ = select.select([primary], [], [], 0.2)
            if ready:
                try:
                    seen += os.read(primary, 4096)
                except OSError:
                    break
        return seen

    try:
        assert b"?- " in read_until(b"?- ", 60)
        os.write(primary, b"sleep(100)\n")
        time.sleep(2.0)                         # the goal's process is running
        os.killpg(proc.pid, signal.SIGINT)      # what Ctrl-C on the terminal sends
        assert b"interrupted" in read_until(b"interrupted", 30)
        os.write(primary, b"type(X, arm)\n")
        assert b"t3" in read_until(b"t3", 30)
        os.write(primary, b"quit\n")
        assert proc.wait(timeout=30) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        os.close(primary)
    assert not _swipl_children()
    assert_untouched(arena)
