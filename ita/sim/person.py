"""A person called to the cell, as the simulator answers for one.

    person = SimPerson(world)
    person.remove_obstacles()          # the time a person takes passes; the cell is clear
    person.replace_tool("us_probe_2")  # a new probe from the stores: its faults are gone

The Exception Handler calls a person for what the cell cannot do itself (kb/faults.pl's
recoveries name the goals, kb/operators.pl's person operators achieve them); the person
is a device on a stream of their own (ita.devices.person), and this is what the simulated
cell makes of their work: each job takes its :data:`SECONDS` on the world's clock and
changes the simulated world, its ground truth (the obstacles the collision model does
not know, the faults switched on), which nothing but the simulator may touch.
"""

from __future__ import annotations

import numpy as np

from ita.sim.faults import Fault
from ita.sim.fixture import seated
from ita.sim.world import SimWorld

__all__ = ["SECONDS", "SimPerson"]

#: simulated seconds a person called to the cell takes for each job (walking in included)
SECONDS = {
    "remove_obstacles": 120.0,
    "reclamp_part": 300.0,
    "replace_tool": 300.0,
    "straighten_probe": 120.0,
}


class SimPerson:
    """A person's jobs in the simulated cell `world`; each returns a line for the reply."""

    def __init__(self, world: SimWorld) -> None:
        self.world = world
        self._reclamps = 0

    def _take(self, job: str) -> float:
        seconds = SECONDS[job]
        self.world.clock.advance(seconds)
        return seconds

    def remove_obstacles(self) -> str:
        """Take every obstacle the collision model does not know out of the cell."""
        seconds = self._take("remove_obstacles")
        removed = [name for name in list(self.world.obstacles) if self.world.remove_obstacle(name)]
        self.world.faults = self.world.faults.without(Fault.OBSTACLE)
        return f"{len(removed)} obstacle(s) removed in {seconds:.0f} s"

    def reclamp_part(self) -> str:
        """Push the part back against its pins and clamp it again: it sits where a new
        draw of the fixture's seating error puts it (ita.sim.fixture), no longer where a
        knock left it."""
        seconds = self._take("reclamp_part")
        world = self.world
        self._reclamps += 1
        world.place_part(seated(world.cell.part, np.random.default_rng([world.seed, 43, self._reclamps])))
        world.faults = world.faults.without(Fault.PART_DISPLACED)
        return f"part re-clamped in {seconds:.0f} s"

    def replace_tool(self, tool: str) -> str:
        """Put a new `tool` from the stores in the old one's place: a new probe is neither
        broken, worn nor crooked; a new SLRA has a working laser and a clean window."""
        seconds = self._take("replace_tool")
        faults = self.world.faults
        for fault in (Fault.BROKEN_PROBE, Fault.WORN_PROBE, Fault.TILTED_PROBE, Fault.SLRA_FAILED,
                      Fault.DIRTY_WINDOW):
            faults = faults.without(fault, tool)
        self.world.faults = faults
        return f"{tool} replaced from the stores in {seconds:.0f} s"

    def straighten_probe(self, tool: str) -> str:
        """Seat the probe `tool` straight in its holder again."""
        seconds = self._take("straighten_probe")
        self.world.faults = self.world.faults.without(Fault.TILTED_PROBE, tool)
        return f"{tool} straightened in {seconds:.0f} s"
