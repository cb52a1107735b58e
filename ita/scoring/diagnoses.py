"""Whether a run's diagnoses named the faults injected into it: what only the simulation
can check."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, TypedDict

__all__ = ["FORMS_OF", "DiagnosisScore", "diagnosis_score"]

#: causes of the fault knowledge base that are a form of an injected fault's cause
FORMS_OF = {"obstacle_at_arm": "obstacle"}


class DiagnosisScore(TypedDict):
    """What :func:`diagnosis_score` finds (see there)."""

    diagnoses: list[dict[str, Any]]
    with_fault: int
    named: int
    unexplained: list[Mapping[str, Any]]


def diagnosis_score(injected: Sequence[Mapping[str, Any]], diagnoses: Sequence[Mapping[str, Any]]) -> DiagnosisScore:
    """Whether the diagnoses named the injected causes: what only the simulation can check.

    Each diagnosis (the archive's ``diagnosis`` event payloads) is held against the
    injected faults that were on while the plan that failed ran: injected before the
    exception and not found gone (injected_faults' ``cleared_time``) before the plan
    began (the diagnosis' ``since``; a transient is spent by the command it hits).  It names the injected
    cause when its cause is one of theirs.  Returns {"diagnoses": [... each with
    "injected" (the candidates' causes) and "named"], "with_fault": diagnoses that had an
    injected fault to find, "named": those that found it, "unexplained": injected faults
    no diagnosis named (some never raised an exception: a glitch met by a command that
    did not need the device)}."""
    rows: list[dict[str, Any]] = []
    named_any: set[int] = set()
    for d in diagnoses:
        t = d.get("t0", 0.0)
        since = d.get("since", t)
        candidates = [i for i, f in enumerate(injected) if f["sim_time"] <= t + 1e-6
                      and (f.get("cleared_time") is None or f["cleared_time"] >= since - 1e-6)]
        cause = d.get("cause") or ""
        name, _, target = cause.partition("(")
        target = target.rstrip(")")
        name = FORMS_OF.get(name, name)
        hit = next((i for i in candidates if injected[i]["cause"] == name
                    and (not target or target in (injected[i]["target"], "gauge", "controller"))), None)
        if hit is not None:
            named_any.add(hit)
        rows.append({"spec": d.get("spec"), "exception": d.get("exception"), "cause": d.get("cause"),
                     "injected": [injected[i]["cause"] for i in candidates], "named": hit is not None,
                     "summary": d.get("summary")})
    with_fault = [r for r in rows if r["injected"]]
    return {"diagnoses": rows, "with_fault": len(with_fault), "named": sum(r["named"] for r in with_fault),
            "unexplained": [f for i, f in enumerate(injected) if i not in named_any]}
