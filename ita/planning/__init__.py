"""The Operation Planner: MACROP lookup first, else plan from scratch, generalize, store.

The planning itself is Prolog (prolog/planner.pl, prolog/macrop.pl, kb/operators.pl);
this package is the facade the executive and the CLI call:

    from ita.planning import OperationPlanner, WorldState
    with OperationPlanner(kb, store_path("bulkhead")) as planner:
        plan = planner.plan_measurement(spec, WorldState(), "us_probe_1")
        state = plan.final_state          # where the arm is, what it holds, afterwards
"""

from ita.planning.operation import (
    MacropInfo,
    NoPlanError,
    OperationPlan,
    OperationPlanner,
    PlanSource,
    PlanStep,
    StoreCounts,
    store_path,
)
from ita.planning.state import Place, PoseKind, QualitativePose, WorldState

__all__ = [
    "MacropInfo",
    "NoPlanError",
    "OperationPlan",
    "OperationPlanner",
    "PlanSource",
    "PlanStep",
    "Place",
    "QualitativePose",
    "PoseKind",
    "StoreCounts",
    "WorldState",
    "store_path",
]
