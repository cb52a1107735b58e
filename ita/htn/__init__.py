"""HTN planning: the engine's Python side (prolog/htn.pl, prolog/hddl.pl).

- :mod:`ita.htn.plan`: an HTN plan as values (actions, root tasks, decompositions),
  and the IPC 2020 plan format, written and read;
- :mod:`ita.htn.solve`: total-order HDDL solved by the engine in a child ``swipl``
  that is killed at its time limit;
- :mod:`ita.htn.hddl`: an HDDL reader of its own, for
- :mod:`ita.htn.verify`: a verifier of plans in the IPC format, independent of the
  engine (executability, and that the decomposition refines the problem's network).
"""

from ita.htn.plan import Decomposition, HtnPlan, PlanFormatError, format_ipc, parse_ipc
from ita.htn.solve import NoPlan, SolveOutcome, solve_hddl
from ita.htn.verify import verify_plan

__all__ = [
    "Decomposition",
    "HtnPlan",
    "NoPlan",
    "PlanFormatError",
    "SolveOutcome",
    "format_ipc",
    "parse_ipc",
    "solve_hddl",
    "verify_plan",
]
