"""Scoring results against true values: false accepts and rejects, errors."""

from __future__ import annotations

import math

import pytest

from ita.archive import Outcome, Result
from ita.scoring.compare import compare


def res(spec_id: str, value: float | None, u: float = 0.01) -> Result:
    if value is None:
        return Result(spec_id, Outcome.NOT_DONE, 2.0, -0.1, 0.1, reason="x")
    return Result(spec_id, Outcome.MEASURED, 2.0, -0.1, 0.1, value=value, u=u)


def test_false_accepts_rejects_and_missed() -> None:
    results = [res("ok", 2.0), res("fa", 2.05), res("fr", 2.2), res("true_reject", 2.3),
               res("unc", 2.09), res("nd", None), res("nope", 2.0)]
    truth = {"ok": 2.01, "fa": 2.11, "fr": 2.09, "true_reject": 2.31, "unc": 2.12, "nd": 1.5}
    sc = compare(results, truth)
    assert sc.false_accepts == ("fa",) and sc.false_rejects == ("fr",)
    assert sc.missed == ("unc", "nd") and sc.unscored == ("nope",)
    assert sc.confusion[("conforms", True)] == 1 and sc.confusion[("does_not_conform", False)] == 1
    assert sc.confusion[("not_done", False)] == 1


def test_error_statistics() -> None:
    sc = compare([res("a", 2.01, u=0.01), res("b", 1.97, u=0.01), res("c", None)],
                 {"a": 2.0, "b": 2.0, "c": 2.0})
    st = sc.error_stats()
    assert st["n"] == 2 and st["mean"] == pytest.approx(-0.01) and st["max_abs"] == pytest.approx(0.03)
    assert st["within_u"] == 0.5  # |0.01| <= 0.02, |-0.03| > 0.02
    assert sc.normalized_errors == pytest.approx([0.5, -1.5])
    assert math.isnan(compare([], {}).error_stats()["mean"])


def test_an_obstacle_found_against_the_arm_names_the_injected_obstacle() -> None:
    from ita.scoring.diagnoses import diagnosis_score

    injected = [{"sim_time": 10.0, "cause": "obstacle", "target": "obstacle_1", "cleared_time": None},
                {"sim_time": 5.0, "cause": "dirty_window", "target": "slra_1", "cleared_time": 8.0}]
    diagnoses = [{"t0": 12.0, "since": 11.0, "cause": "obstacle_at_arm", "exception": "bump"},
                 {"t0": 12.5, "since": 11.0, "cause": "dirty_window(slra_1)", "exception": "too_few_pixels"}]
    score = diagnosis_score(injected, diagnoses)
    assert [r["named"] for r in score["diagnoses"]] == [True, False]   # the window was clean again by then
    assert score["with_fault"] == 2 and score["named"] == 1
