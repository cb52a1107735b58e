"""Fuzzing the readers and commands with malformed input (hypothesis): spec files, TSPLIB
files, PDDL domains and problems, and argument bytes.  Every case ends in a result or a
clear error (InputError / exit 2), never a traceback, and a failed import writes nothing.

The default suite runs a few cases of each; the slow suite (``-m slow``) over 10,000:

    .venv/bin/python -m pytest -q -p no:cacheprovider -m slow tests/test_fuzz_inputs.py
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ita.cli import main
from ita.errors import InputError, PrologError
from ita.sequence.tsplib import parse_tsplib
from ita.specs.io import COLUMNS, parse_specs_text

FAST = 15
SLOW = {"specs": 4000, "tsp": 3000, "pddl": 2000, "args": 1000, "import": 300}
_SETTINGS = dict(deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                       HealthCheck.too_slow, HealthCheck.data_too_large])

HEADER = ",".join(COLUMNS)
GOOD_ROW = "WT-1,web_thickness,P,10.0,20.0,3.0,0.0,0.0,1.0,2.5,-0.127,0.127,A,,,,"
CSV_PIECES = st.sampled_from([",", '"', '""', "\n", "\r\n", "\ufeff", "nan", "inf", "-", "1e308", "1e-308",
                              "web_thickness", "hole_diameter", "id", "kind", "  ", "\x00", "é", "#", "0",
                              "-0.127", "0.127", "A", "WT-1", ";", "\t"])


def _mutated(base: str, pieces: list[str], cuts: list[int]) -> str:
    text = base
    for piece, cut in zip(pieces, cuts):
        at = cut % (len(text) + 1)
        text = text[:at] + piece + text[at:]
    return text


spec_texts = st.one_of(
    st.text(max_size=300),
    st.builds(_mutated, st.just(HEADER + "\n" + GOOD_ROW + "\n"), st.lists(CSV_PIECES, max_size=8),
              st.lists(st.integers(min_value=0, max_value=400), min_size=8, max_size=8)),
    st.builds(lambda rows: HEADER + "\n" + "\n".join(rows), st.lists(
        st.lists(st.one_of(st.text(max_size=8), st.sampled_from(["1", "-1", "nan", "1e400", "web_thickness"])),
                 min_size=0, max_size=20).map(lambda cells: ",".join(cells)), max_size=5)),
)


def _check_spec_text(text: str) -> None:
    try:
        table = parse_specs_text(text, "fuzz.csv")
    except InputError as exc:
        assert str(exc).startswith("fuzz.csv")
        return
    for spec in table.specs:
        assert spec.id


@settings(max_examples=FAST, **_SETTINGS)
@given(spec_texts)
def test_spec_text(text):
    _check_spec_text(text)


@pytest.mark.slow
@settings(max_examples=SLOW["specs"], **_SETTINGS)
@given(spec_texts)
def test_spec_text_many(text):
    _check_spec_text(text)


# -- TSPLIB ------------------------------------------------------------------------------

TSP_GOOD = "NAME: t\nTYPE: TSP\nDIMENSION: 3\nEDGE_WEIGHT_TYPE: EUC_2D\nNODE_COORD_SECTION\n1 0 0\n2 3 4\n3 1 1\nEOF\n"
TSP_PIECES = st.sampled_from(["\n", ":", " ", "1e308", "-1e308", "nan", "inf", "DIMENSION: 100000", "EOF",
                              "NODE_COORD_SECTION", "EDGE_WEIGHT_SECTION", "TYPE: ATSP", "0", "-1", "x", "\t",
                              "DIMENSION: 0", "DIMENSION: -3", "9" * 30])
tsp_texts = st.one_of(
    st.text(max_size=200),
    st.builds(_mutated, st.just(TSP_GOOD), st.lists(TSP_PIECES, max_size=6),
              st.lists(st.integers(min_value=0, max_value=200), min_size=6, max_size=6)),
)


def _check_tsp_text(text: str) -> None:
    import numpy as np

    try:
        problem = parse_tsplib(text, "fuzz.tsp")
    except InputError as exc:
        assert str(exc).startswith("fuzz.tsp")
        return
    matrix = problem.matrix()
    assert np.isfinite(matrix).all()


@settings(max_examples=FAST, **_SETTINGS)
@given(tsp_texts)
def test_tsp_text(text):
    _check_tsp_text(text)


@pytest.mark.slow
@settings(max_examples=SLOW["tsp"], **_SETTINGS)
@given(tsp_texts)
def test_tsp_text_many(text):
    _check_tsp_text(text)


# -- PDDL --------------------------------------------------------------------------------

DOMAIN = """(define (domain hand)
  (:requirements :strips)
  (:predicates (at ?x) (holding ?x) (free))
  (:action pick :parameters (?x) :precondition (and (at ?x) (free))
    :effect (and (holding ?x) (not (at ?x)) (not (free)))))
"""
PROBLEM = "(define (problem two) (:domain hand) (:objects a b) (:init (at a) (at b) (free)) (:goal (and (holding b))))\n"
PDDL_PIECES = st.sampled_from(["(", ")", " ", "-", "?x", ":typing", "(when (free) (at ?x))", "(or (at a))",
                               "(forall (?y) (at ?y))", ":goal", ":domain", "other", "(not", ";", "\n", "ball",
                               "(:requirements :fluents)", "(= ?x ?x)", "\x00", "é", "(at)", "(at a b)"])
pddl_pairs = st.tuples(
    st.builds(_mutated, st.just(DOMAIN), st.lists(PDDL_PIECES, max_size=5),
              st.lists(st.integers(min_value=0, max_value=400), min_size=5, max_size=5)),
    st.builds(_mutated, st.just(PROBLEM), st.lists(PDDL_PIECES, max_size=5),
              st.lists(st.integers(min_value=0, max_value=200), min_size=5, max_size=5)),
)


def _check_pddl(knowledge_base, where: Path, domain: str, problem: str) -> None:
    from ita.logic.terms import Var

    d, p = where / "domain.pddl", where / "problem.pddl"
    d.write_text(domain, encoding="utf-8")
    p.write_text(problem, encoding="utf-8")
    try:
        knowledge_base.once("pddl", "pddl_task", str(d), str(p), Var("_T"))
    except PrologError as exc:
        assert exc.message  # a message, whatever the reader found


@settings(max_examples=FAST, **_SETTINGS)
@given(pddl_pairs)
def test_pddl(knowledge_base, tmp_path, pair):
    _check_pddl(knowledge_base, tmp_path, *pair)


@pytest.mark.slow
@settings(max_examples=SLOW["pddl"], **_SETTINGS)
@given(pddl_pairs)
def test_pddl_many(knowledge_base, tmp_path, pair):
    _check_pddl(knowledge_base, tmp_path, *pair)


# -- argument bytes ----------------------------------------------------------------------

COMMANDS = [["spec", "show"], ["results"], ["runs", "--json", "--runs-dir"], ["sequence", "tsp"],
            ["report", "last", "-o"], ["part", "info", "--part"]]


def _check_args(tmp_path: Path, command: list[str], raw: bytes) -> None:
    arg = raw.decode("utf-8", "surrogateescape")
    args = [*command, arg]
    if command == ["results"]:
        args += ["--runs-dir", str(tmp_path / "runs")]
    cwd = os.getcwd()
    os.chdir(tmp_path)  # a relative name the command might write lands here
    try:
        result = CliRunner().invoke(main, args)
    finally:
        os.chdir(cwd)
    assert result.exit_code in (0, 1, 2), (args, result.output)
    assert result.exception is None or isinstance(result.exception, SystemExit), (args, repr(result.exception))
    assert "Traceback" not in result.output


arg_cases = st.tuples(st.sampled_from(COMMANDS), st.binary(min_size=1, max_size=40))


@settings(max_examples=FAST, **_SETTINGS)
@given(arg_cases)
def test_argument_bytes(builtin_part, tmp_path, case):
    _check_args(tmp_path, *case)


@pytest.mark.slow
@settings(max_examples=SLOW["args"], **_SETTINGS)
@given(arg_cases)
def test_argument_bytes_many(builtin_part, tmp_path, case):
    _check_args(tmp_path, *case)


# -- a failed import writes nothing -------------------------------------------------------

@pytest.fixture(scope="module")
def part_copy(builtin_part, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("fuzz") / "bulkhead"
    assert CliRunner().invoke(main, ["part", "build", "-o", str(out)]).exit_code == 0
    return out


def _check_import(part: Path, where: Path, text: str) -> None:
    before = (part / "specs.csv").read_bytes()
    source = where / "import.csv"
    source.write_text(text, encoding="utf-8", errors="surrogateescape")
    result = CliRunner().invoke(main, ["spec", "import", str(source), "--part", str(part)])
    assert result.exception is None or isinstance(result.exception, SystemExit), repr(result.exception)
    if result.exit_code != 0:
        assert result.exit_code == 2, result.output
        assert (part / "specs.csv").read_bytes() == before  # nothing written
    else:
        (part / "specs.csv").write_bytes(before)  # undo a valid import for the next case
    assert sorted(p.name for p in part.iterdir() if p.name.startswith(".specs.csv.") and p.suffix == ".tmp") == []


@settings(max_examples=5, **_SETTINGS)
@given(spec_texts)
def test_import(part_copy, tmp_path, text):
    _check_import(part_copy, tmp_path, text)


@pytest.mark.slow
@settings(max_examples=SLOW["import"], **_SETTINGS)
@given(spec_texts)
def test_import_many(part_copy, tmp_path, text):
    _check_import(part_copy, tmp_path, text)
