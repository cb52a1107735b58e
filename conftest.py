"""Collect the plunit tests of prolog/ and kb/ as pytest items, one item per plunit test.

For each ``name.plt`` (beside ``name.pl``) a ``swipl`` subprocess lists the tests at
collection time; the first test of the file to run runs the whole file once in another
``swipl`` subprocess, which prints one JSON line per test.  A test fails when plunit
reports it failed, or when it printed a warning or error (a stray choice point, say).
Fixtures live in tests/conftest.py; this file holds the collector only.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import tempfile
from pathlib import Path
from typing import Any, Iterator

import pytest

_RUNNER = r"""
:- use_module(library(plunit)).
:- use_module(library(http/json)).
:- dynamic captured/2, capturing/0.

:- multifile user:message_hook/3.
:- dynamic in_runner_hook/0.

% Record the errors and warnings that would be printed: those no other hook handles.
user:message_hook(Term, Kind, Lines) :-
    capturing,
    \+ in_runner_hook,
    memberchk(Kind, [error, warning]),
    (   setup_call_cleanup(assertz(in_runner_hook),
                           user:message_hook(Term, Kind, Lines),
                           retractall(in_runner_hook))
    ->  true
    ;   with_output_to(string(S), print_message_lines(current_output, '', Lines)),
        assertz(captured(Kind, S)),
        fail
    ).

emit(Dict) :- json_write_dict(current_output, Dict, [width(0)]), nl.

load(Pl, Plt) :-
    setup_call_cleanup(assertz(capturing),
        ( ( exists_file(Pl) -> load_files(user:Pl, [if(not_loaded)]) ; true ),
          (   source_file_property(Pl, module(M)) -> true ; M = user ),
          load_files(M:Plt, [if(changed)])
        ),
        retractall(capturing)),
    forall(retract(captured(error, S)), emit(_{kind: load_error, message: S})).

list_tests :-
    forall(current_test(Unit, Test, Line, _, _),
           ( format(atom(T), "~w", [Test]),
             emit(_{kind: test, unit: Unit, test: T, line: Line}) )).

run_all :-
    forall(current_test(Unit, Test, Line, _, _), run_one(Unit, Test, Line)).

run_one(Unit, Test, Line) :-
    retractall(captured(_, _)),
    setup_call_cleanup(assertz(capturing),
        catch(ignore(run_tests(Unit:Test)), E, print_message(error, E)),
        retractall(capturing)),
    outcome(Unit, Test, Outcome0),
    findall(S, captured(_, S), Messages),
    atomic_list_concat(Messages, '', Message),
    (   Outcome0 == passed, Messages \== [] -> Outcome = failed ; Outcome = Outcome0 ),
    format(atom(T), "~w", [Test]),
    emit(_{kind: result, unit: Unit, test: T, line: Line, outcome: Outcome,
           message: Message}).

% A forall(Generator) test records its results under the name Test@Bindings.
outcome(Unit, Test, failed) :- plunit:failed(Unit, T, _, _), named(Test, T), !.
outcome(Unit, Test, failed) :-
    plunit:failed_assertion(Unit, T, _, _, _, _, _), named(Test, T), !.
outcome(Unit, Test, failed) :- plunit:sto(Unit, T, _, _), named(Test, T), !.
outcome(Unit, Test, skipped) :- plunit:blocked(Unit, T, _, _), named(Test, T), !.
outcome(Unit, Test, passed) :- plunit:fixme(Unit, T, _, _, _), named(Test, T), !.
outcome(Unit, Test, passed) :- plunit:passed(Unit, T, _, _, _), named(Test, T), !.
outcome(Unit, Test, Outcome) :-
    plunit:current_test(Unit, Test, _, _, Options),
    memberchk(forall(_), Options), !,
    Outcome = passed.                   % a generator without solutions: nothing ran
outcome(_, _, failed).

named(Test, Recorded) :- Recorded == Test, !.
named(Test, Test@_).

main :-
    current_prolog_flag(argv, [Mode, Pl, Plt]),
    load(Pl, Plt),
    (   Mode == list -> list_tests ; run_all ).
"""


def _swipl(mode: str, plt: Path) -> list[dict[str, Any]]:
    """Run the runner in `mode` ("list" or "run") on `plt`; its JSON lines."""
    swipl = shutil.which("swipl")
    if swipl is None:
        raise pytest.UsageError("swipl is not installed; the plunit tests need it")
    with tempfile.TemporaryDirectory() as tmp:
        runner = Path(tmp) / "plunit_runner.pl"
        runner.write_text(_RUNNER, encoding="utf-8")
        proc = subprocess.run(
            [swipl, "-q", "-g", "main", "-t", "halt", str(runner),
             mode, str(plt.with_suffix(".pl")), str(plt)],
            capture_output=True, text=True, timeout=600, cwd=plt.parent,
        )
    records = [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]
    errors = [r["message"] for r in records if r["kind"] == "load_error"]
    if errors:
        raise PlunitLoadError(f"{plt}: failed to load:\n" + "".join(errors))
    if proc.returncode != 0 and not records:
        raise PlunitLoadError(f"{plt}: swipl exited {proc.returncode}:\n{proc.stderr}")
    return records


class PlunitLoadError(Exception):
    """A .plt file (or the .pl it tests) does not load."""


class PlunitFailure(Exception):
    """A plunit test failed; the message is plunit's report."""


class PltFile(pytest.File):
    """A plunit test file; its items are its tests."""

    _results: dict[tuple[str, str], dict[str, Any]] | None = None

    def collect(self) -> Iterator["PltItem"]:
        for record in _swipl("list", self.path):
            if record["kind"] == "test":
                yield PltItem.from_parent(
                    self, name=f"{record['unit']}:{record['test']}",
                    unit=record["unit"], test=record["test"], line=record["line"],
                )

    def result(self, unit: str, test: str) -> dict[str, Any] | None:
        """The outcome of one test, running the whole file on first request."""
        if self._results is None:
            self._results = {
                (r["unit"], r["test"]): r for r in _swipl("run", self.path) if r["kind"] == "result"
            }
        return self._results.get((unit, test))


class PltItem(pytest.Item):
    """One plunit test."""

    def __init__(self, *, unit: str, test: str, line: int, **kwargs: Any):
        super().__init__(**kwargs)
        self.unit, self.test, self.line = unit, test, line

    def runtest(self) -> None:
        assert isinstance(self.parent, PltFile)
        result = self.parent.result(self.unit, self.test)
        if result is None:
            raise PlunitFailure("the test did not report a result (did swipl crash?)")
        if result["outcome"] == "skipped":
            pytest.skip(result["message"] or "blocked")
        if result["outcome"] != "passed":
            raise PlunitFailure(result["message"] or "failed")

    def repr_failure(self, excinfo: pytest.ExceptionInfo[BaseException], style: Any = None) -> str:
        if isinstance(excinfo.value, (PlunitFailure, PlunitLoadError)):
            return f"{self.path}:{self.line}: plunit test {self.name} failed\n{excinfo.value}"
        return str(super().repr_failure(excinfo))

    def reportinfo(self) -> tuple[Path, int, str]:
        return self.path, self.line - 1, f"plunit {self.name}"


def pytest_collect_file(parent: pytest.Collector, file_path: Path) -> PltFile | None:
    """Turn each .plt file under prolog/ or kb/ into a PltFile."""
    if file_path.suffix == ".plt" and file_path.parent.name in ("prolog", "kb"):
        return PltFile.from_parent(parent, path=file_path)
    return None
