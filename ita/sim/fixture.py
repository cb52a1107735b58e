"""Where the simulated part really sits: its nominal placement moved by the fixture's error.

No fixture puts a part where its model says to the micrometre.  The part rests on its
datum face A on the fixture's pads (flat and fixed: they set its height and tilt, which
this model keeps nominal) and is pushed against pins by hand: its place in the plane of
face A and its turn about the face's normal are off by a few tenths of a millimetre and a
tenth of a degree or two, a new draw every time it is clamped.  A knock displaces it much
further (:func:`knocked`).

    placement = seated(cell.part, rng)          # the truth of one run
    placement = knocked(placement, rng)         # after a knock mid-run

Both turn the part about the middle of its envelope.

Only the simulator holds the result (``SimWorld.part_placement``); the measuring side
finds it by registering the part on its datums (ita.task.align).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ita.workcell.model import PartPlacement

FloatArray = NDArray[np.float64]

__all__ = ["FixtureError", "KNOCK", "SEATING", "knocked", "seated"]


@dataclass(frozen=True)
class FixtureError:
    """A draw of how far the part sits off: shift (mm, 1 sigma, per axis in the plane of
    face A) and turn about face A's normal (degrees, 1 sigma), each cut at `cut` sigma."""

    shift_mm: float
    turn_deg: float
    cut: float = 2.5

    def draw(self, rng: np.random.Generator) -> tuple[FloatArray, float]:
        """(shift (3,) mm, turn rad) of one draw."""
        xy = np.clip(rng.normal(0.0, 1.0, 2), -self.cut, self.cut) * self.shift_mm
        turn = float(np.clip(rng.normal(0.0, 1.0), -self.cut, self.cut)) * np.radians(self.turn_deg)
        return np.array([xy[0], xy[1], 0.0]), turn


#: the part pushed against its pins and clamped: a few tenths of a millimetre and of a degree
SEATING = FixtureError(shift_mm=0.25, turn_deg=0.1)
#: the part knocked on the fixture (a fault): millimetres and tenths of a degree
KNOCK = FixtureError(shift_mm=1.5, turn_deg=0.2)


def _turned(placement: PartPlacement, shift: FloatArray, turn: float) -> PartPlacement:
    c, s = np.cos(turn), np.sin(turn)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    m = (np.asarray(placement.envelope_min_mm, dtype=float) + np.asarray(placement.envelope_max_mm, dtype=float)) / 2
    return placement.moved(rot, m - rot @ m + shift)       # turned about the part's middle, then shifted


def seated(nominal: PartPlacement, rng: np.random.Generator, error: FixtureError = SEATING) -> PartPlacement:
    """Where a clamping puts the part: `nominal` turned about its middle and shifted by a
    draw of `error`."""
    shift, turn = error.draw(rng)
    return _turned(nominal, shift, turn)


def knocked(placement: PartPlacement, rng: np.random.Generator, error: FixtureError = KNOCK) -> PartPlacement:
    """Where a knock puts the part that sat at `placement`."""
    shift, turn = error.draw(rng)
    return _turned(placement, shift, turn)
