"""The loaded system a run (or one measurement) needs: knowledge bases, part, plans,
MKB, simulator and devices.

    session = open_session(part_dir, seed=1, progress=print)   # prepares first if needed
    ...
    session.close()                                            # saves the MACROP store
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ita.devices import ArmDevice, GaugeCommands, PersonDevice, SlraDevice
from ita.devices.stations import StationCommands
from ita.collision import Regions
from ita.executive import PlanExecutive
from ita.executive.conductor import folded_ground
from ita.geometry import GeometricReasoner
from ita.kinematics import ArmModel
from ita.kinematics.fk import FloatArray
from ita.logic.bridge import KnowledgeBase
from ita.logic.world import WorldModel
from ita.offline.prepare import prepare_inspection
from ita.part.serials import design_params, serial_asbuilt
from ita.part.specfile import check_measurable
from ita.part.store import load_part
from ita.path import PathPlanner, planners_for
from ita.planning import OperationPlanner, store_path
from ita.robot.gate import MotionGate
from ita.sensors.ultrasonic import UltrasonicGauge
from ita.sequence.plan import planning_context, with_mkb
from ita.sequence.store import apply_tool_marks, load_tool_marks
from ita.sim.fixture import seated
from ita.sim.person import SimPerson
from ita.sim.slra import SlraScene
from ita.sim.ultrasonic import UltrasonicSim
from ita.sim.world import SimClock, SimWorld, simulated_part
from ita.task.align import Alignment, datums_of
from ita.vision.for_part import vision_context

if TYPE_CHECKING:
    from ita.devices import ArmDevice, PersonDevice, SlraDevice
    from ita.executive import PlanExecutive
    from ita.geometry import GeometricReasoner
    from ita.geometry.mkb import MeasurementKB
    from ita.logic.bridge import KnowledgeBase
    from ita.part.model import Part
    from ita.planning import OperationPlanner
    from ita.sequence.plan import PlanningContext, SequencePlan
    from ita.workcell import ToolSpec
    from ita.sim.world import SimWorld, simulated_part
    from ita.specs.model import MeasurementSpec

__all__ = ["Session", "open_session"]


@dataclass(eq=False)
class Session:
    """The loaded system: knowledge bases, part, plan, MKB, simulator and devices.

    part_arg: --part as given (None: the built-in bulkhead); plan: the prepared
    sequence plan; arm, slra, person: the devices of the executive's streams (the
    person: someone called to the cell, answered by the simulator).
    """

    kb: KnowledgeBase
    part: Part
    part_arg: str | None
    ctx: PlanningContext
    plan: SequencePlan
    mkb: MeasurementKB
    reasoner: GeometricReasoner
    world: SimWorld
    arm: ArmDevice
    slra: SlraDevice
    person: PersonDevice
    executive: PlanExecutive
    planner: OperationPlanner
    seed: int
    setup_seconds: float = 0.0
    simulated: str = "generated"
    #: a serial's own as-built part (ita.part.serials), its directory relative to the part's
    asbuilt_dir: str | None = None
    #: where the part was registered on its datums (ita.task.align; None: not registered)
    alignment: Alignment | None = None
    #: the other arm of a two-arm run (ita.robot.gate): the part's registration is posted
    #: to it by the arm that registers, and taken from it by the other (None: one arm)
    peer: MotionGate | None = None
    #: whether this arm registers the part (else it takes the other arm's registration)
    registers: bool = True
    #: ground the Path Planner keeps the arm out of besides the cell (open_session's others_folded)
    keep_clear: Regions | None = None
    _specs: dict[str, MeasurementSpec] = field(default_factory=dict, repr=False)
    _specs_of: PlanningContext | None = field(default=None, repr=False)   # the context _specs are of

    @property
    def specs(self) -> dict[str, MeasurementSpec]:
        """Spec id -> spec (made once per planning context: the loop asks for it per result)."""
        if self._specs_of is not self.ctx:
            self._specs = {s.id: s for s in self.ctx.specs}
            self._specs_of = self.ctx
        return self._specs

    @property
    def clock(self) -> SimClock:
        """The cell's simulated clock (the executive's too)."""
        return self.world.clock

    @property
    def held(self) -> str | None:
        """The tool the arm holds now (None: none)."""
        return self.world.held

    @property
    def joints(self) -> FloatArray:
        """The arm's joint positions now, as its controller reports them (rad)."""
        return self.world.q

    @property
    def arm_model(self) -> ArmModel:
        """The arm's kinematic model (from the workcell's URDF)."""
        return self.world.model

    def planned_tool(self, spec_id: str) -> str | None:
        """The tool the prepared sequence plan takes `spec_id` with (None: not planned)."""
        return next((g.tool for g in self.plan.groups if spec_id in g.order), None)

    def close(self) -> None:
        """Save the MACROP store (kept open: SWI-Prolog has one database per process, which
        another session in this process may share) and close the simulator."""
        try:
            self.planner.save()
        finally:
            self.world.close()


def open_session(part_dir: Path | None = None, *, seed: int = 0,
                 progress: Callable[[str], None] = lambda _m: None, serial: str | None = None,
                 shifts: Mapping[str, float] | None = None, placement_error: bool = False,
                 arm: str | None = None, away_tools: Mapping[str, str] | None = None,
                 others_folded: bool = False) -> Session:
    """Load everything a run needs; prepare the part first (sequence plan, MKB, MACROPs)
    when what is stored is missing or stale.  serial: the simulator holds that serial's own
    as-built part of a generated design (shifts: special causes asked, spec id -> mm;
    ita.part.serials); another part keeps its one as-built part.  placement_error: the
    simulator seats the part off its nominal placement as a fixture does (ita.sim.fixture,
    a draw of `seed`; only a part with datum holes to register it on, ita.task.align).
    arm: the cell's arm that works (default its first; the second works the cell alone,
    with its own plan, MKB and MACROPs: ita.sequence.plan.planning_context).  away_tools:
    tool -> the arm it is kept for (the other arm's own, in a two-arm run): reserved to
    this session's world model (kb/world.pl reserved/2), so this arm never takes it.
    others_folded: the Path Planner keeps this arm out of the ground where the cell's other
    arm may stand folded (a two-arm run: ita.executive.conductor.folded_ground)."""

    t0 = time.perf_counter()
    progress("loading the knowledge bases and the part")
    kb = KnowledgeBase()
    apply_tool_marks(kb, load_tool_marks())
    for tool, keeper in sorted((away_tools or {}).items()):
        WorldModel(kb).set_reserved(tool, keeper)
    part = load_part(part_dir)
    check_measurable(part)                # no specs, or features the mesh does not show: say so first
    asbuilt_dir: str | None = None
    if serial is not None and (shifts or design_params(part) is not None):
        made = serial_asbuilt(part, serial, shifts)
        simulated = simulated_part(made.directory, part.mesh)
        asbuilt_dir = str(made.directory.relative_to(part.directory))
    else:
        simulated = simulated_part(part.directory, part.mesh)  # a bad as-built mesh is named before preparing
    ctx = planning_context(part_dir, kb=kb, part=part, arm=arm)
    keep_clear = folded_ground(ctx.workcell) if others_folded else None
    plan, mkb, _ = prepare_inspection(ctx, part, progress=progress, warm=False)
    ctx = with_mkb(ctx, mkb)              # a resequencing keeps what the MKB could not place
    specs = {s.id: s for s in ctx.specs}
    cell = ctx.workcell
    reasoner = GeometricReasoner(mkb, cell, ctx.specs)
    progress("building the simulated workcell")
    truth = cell.part
    if placement_error and len(datums_of(part.features, ctx.specs)) >= 2:
        truth = seated(truth, np.random.default_rng([seed, 41]))
    world = SimWorld(cell, part.directory, asbuilt_mesh=simulated.mesh, seed=seed, q0=reasoner.home,
                     part_placement=truth)
    try:
        gauge_sim = UltrasonicSim(world)
        ut = UltrasonicGauge(gauge_sim)
        gauge = GaugeCommands(ut, specs)
        arm_device = ArmDevice(world, reasoner, planners_for(cell, part, keep_clear=keep_clear), extra=gauge.handlers)
        reasoner.check_with(lambda q, tool: _free(arm_device.planner_for(tool), q))     # the planners of now
        arm_device.add_handlers(StationCommands(world, reasoner, arm_device.controller, gauge_sim, gauge=ut).handlers, "station_s")
        slra_tools = [t for t in cell.tools if t.tool_class.value == "slra_tool"]
        vctx = vision_context(part, cell, tool=slra_tools[0].name if slra_tools else "slra_1",
                                       specs=list(ctx.specs))
        scene = SlraScene.from_simulated(simulated, cell, placement=world.part_placement)
        slra = SlraDevice(world, scene, reasoner, vctx, specs, np.random.default_rng([seed, 21]))
        person = PersonDevice(SimPerson(world), world.clock)
        executive = PlanExecutive(kb, {"path_planner": arm_device, "vision": slra, "person": person}, clock=world.clock)
        op = OperationPlanner(kb, store_path(ctx.part_name))
    except BaseException:
        world.close()
        raise
    return Session(kb, part, None if part_dir is None else str(Path(part_dir).resolve()), ctx, plan, mkb,
                   reasoner, world, arm_device, slra, person, executive, op, seed, time.perf_counter() - t0, simulated.source,
                   asbuilt_dir, keep_clear=keep_clear)


def _free(planner: tuple[PathPlanner, ToolSpec | None], q: FloatArray) -> NDArray[np.bool_]:
    """Which configurations ``q`` (n, 6) the planner for the tool in hand finds free."""
    return planner[0].config_free(q, planner[1])
