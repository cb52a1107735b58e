"""The Path Planner: collision-free, timed arm motions in the workcell (seed, Path Planner).

Two levels, as in the 1987 system: the tool point among the regions grown by the tool's
size (`visibility`: visibility lines and A*), then the whole arm at incremental positions
along the lifted path, with intermediate subgoals where a link would collide (`lift`);
where those give up within their effort bound, a bidirectional sampling planner in joint
space on the same checks (`sampling`: RRT-Connect); then shortening, corners blended
over the lookahead queue and a velocity profile within every joint's limits (`smooth`).

    from ita.path import PathPlanner, workcell_planner
    planner, tool = workcell_planner(load_workcell(), load_part(None), held="us_probe_1")
    result = planner.plan(q_start, goal_tool_poses, tool)     # or a goal configuration (6,)
    result.ok, result.reason, result.trajectory.times, result.trajectory.q

Modules: `visibility`, `lift`, `motion` (configuration and sound motion checks),
`sampling` (the fallback), `smooth`, `planner` (the facade), `problems` (problem sets),
`render` (pictures), `trajectory` (the timed trajectory the controller runs).  The planner
takes an ArmModel, a RegionTree and an ArmChecker and hands plain callables
(`config_free`, `motion_free`) to the levels below; no simulator.
"""

from ita.path.planner import (
    HOME,
    PathFailure,
    PathPlanner,
    PathResult,
    PlannerSettings,
    arm_with_tool,
    checker_for,
    planners_for,
    workcell_planner,
)
from ita.path.smooth import limit_violations, time_parameterize
from ita.path.trajectory import TimedTrajectory

__all__ = [
    "HOME",
    "PathPlanner",
    "PathResult",
    "PlannerSettings",
    "PathFailure",
    "TimedTrajectory",
    "arm_with_tool",
    "checker_for",
    "limit_violations",
    "planners_for",
    "time_parameterize",
    "workcell_planner",
]
