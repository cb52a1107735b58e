"""The controller's interlock with another arm's: every motion claims its space first.

An arm that shares the cell with another asks, before each motion, for the zones the
motion sweeps and the pose it ends in (the cell's zone conductor,
ita.executive.conductor, answers for both arms).  The answer is a :class:`Grant`:

- ``go``: start after ``wait_s`` simulated seconds (the WAIT until the other arm's
  release; the claim's CONTINUE);
- ``fold``: after ``wait_s``, first fold back to ``fold`` (the other arm needs where this
  one stands), then ask again for the way back and the motion;
- ``refuse``: the motion cannot be granted (the other arm is down, or neither can give
  way): the controller replies REJECTED and the arm stays where it is.

After each motion the controller says where the arm ended (``moved``: a bump stops it
short of the claimed end); at the end of its work the arm parks (``park``: a fold like
the above) and says it is ``done``.

The same line carries what the arms share besides space, in simulated time: one arm
``post``s a fact (the part's registration on its datums), the other ``take``s it, waiting
until the simulated time it was posted (None when the poster ended without one); and
one arm ``tell``s the other news (a diagnosis found the part displaced and registered it
again, a shared tool's condition), which that arm hears with the answer to its next claim.

    gate = RemoteGate(connection)            # a multiprocessing Connection to the conductor
    controller.gate = gate                   # RobotController asks it before every motion

Messages on the connection are tuples (name, arm's clock, arrays): ``("claim", t,
times, q)`` answered by ``(kind, wait_s, fold q or None, why)``; ``("moved", t, q)``;
``("park", t, q)`` answered like a claim; ``("done", t)``; ``("post", t, key, value)``;
``("take", t, key[, of_work])`` answered by ``(wait_s, value)``; ``("tell", t, value)``: news
for the other arm, which gets it as a fifth item of the answer to its first claim at `t` or
later (``((t, value), ...)``); ``("clock", t)``: the arm's clock
passed `t` (:meth:`RemoteGate.clock`: it makes no claim before, so the conductor may decide
the other arm's claims up to `t` without waiting for this one's next: the same decisions,
sooner in wall time).
"""

from __future__ import annotations

from dataclasses import dataclass
from multiprocessing.connection import Connection
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

__all__ = ["Grant", "MotionGate", "RemoteGate"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Grant:
    """The conductor's answer to a claim (see the module docstring)."""

    kind: str                           # "go", "fold" or "refuse"
    wait_s: float = 0.0
    fold: tuple[float, ...] | None = None
    why: str = ""


class MotionGate(Protocol):
    """What the robot controller asks before and tells after each motion."""

    def claim(self, t: float, times: FloatArray, q: FloatArray, pinned: bool = False) -> Grant: ...

    def moved(self, t: float, q: FloatArray, flown: tuple[FloatArray, FloatArray] | None = None) -> None: ...

    def park(self, t: float, q: FloatArray) -> Grant: ...

    def done(self, t: float) -> None: ...

    def post(self, t: float, key: str, value: object) -> None: ...

    def take(self, t: float, key: str, of_work: bool = False) -> tuple[float, object]: ...

    def tell(self, t: float, value: object) -> None: ...

    def heard(self) -> list[tuple[float, object]]: ...

    def unread(self) -> list[tuple[float, object]]: ...

    def told(self, kind: str) -> float | None: ...

    def clock(self, t: float) -> None: ...


#: an arm's clock is told to the conductor when it has moved this far (s) past what the
#: conductor knows of it (a message per control period would cost more than it saves)
CLOCK_STEP_S = 0.2


class RemoteGate:
    """A :class:`MotionGate` whose conductor runs in another process, over `connection`."""

    def __init__(self, connection: Connection) -> None:
        self.connection = connection
        self.known_s = 0.0               # the arm's time the conductor knows it has reached
        self.news: list[tuple[float, object]] = []     # the other arm's news heard, not yet read
        self._kinds: dict[str, float] = {}             # kind of news -> when last told (heard so far)

    def _ask(self, message: tuple[object, ...]) -> Grant:
        self.connection.send(message)
        kind, wait_s, fold, why, *news = self.connection.recv()
        if news:
            self._hear(news[0])
        return Grant(str(kind), float(wait_s), None if fold is None else tuple(map(float, fold)), str(why))

    def _told(self, t: float) -> None:
        self.known_s = max(self.known_s, float(t))

    def claim(self, t: float, times: FloatArray, q: FloatArray, pinned: bool = False) -> Grant:
        """Ask for the zones of a motion; pinned: the arm cannot fold before it (its probe
        is pressed on the part: this motion takes it off)."""
        times = np.asarray(times, dtype=float)
        grant = self._ask(("claim", float(t), times, np.asarray(q, dtype=float), bool(pinned)))
        self._told(t + grant.wait_s + (float(times[-1]) if grant.kind == "go" else 0.0))
        return grant

    def clock(self, t: float) -> None:
        """The arm's clock reached `t` (SimClock.on_advance): told when it is CLOCK_STEP_S past
        what the conductor knows (a granted motion's end, the last message's time)."""
        if t >= self.known_s + CLOCK_STEP_S:
            self.connection.send(("clock", float(t)))
            self.known_s = float(t)

    def moved(self, t: float, q: FloatArray, flown: tuple[FloatArray, FloatArray] | None = None) -> None:
        """Where the arm is at `t` after its last motion; flown: the (times, joints) of the way
        a fold took (of those the conductor claimed for it)."""
        message: tuple[object, ...] = ("moved", float(t), np.asarray(q, dtype=float))
        if flown is not None:
            message += (np.asarray(flown[0], dtype=float), np.asarray(flown[1], dtype=float))
        self.connection.send(message)
        self._told(t)

    def park(self, t: float, q: FloatArray) -> Grant:
        return self._ask(("park", float(t), np.asarray(q, dtype=float)))

    def done(self, t: float) -> None:
        self.connection.send(("done", float(t)))

    def post(self, t: float, key: str, value: object) -> None:
        self.connection.send(("post", float(t), key, value))
        self._told(t)

    def take(self, t: float, key: str, of_work: bool = False) -> tuple[float, object]:
        """The fact `key` (waiting in simulated time until posted); of_work: only the other
        arm's work posts it, so None when that arm is done or itself waits for a fact."""
        self.connection.send(("take", float(t), key, bool(of_work)) if of_work else ("take", float(t), key))
        wait_s, value, *news = self.connection.recv()
        if news:
            self._hear(news[0])
        return float(wait_s), value

    def _hear(self, news: list[tuple[float, object]]) -> None:
        for at, value in news:
            self.news.append((float(at), value))
            if isinstance(value, dict) and isinstance(value.get("kind"), str):
                self._kinds[value["kind"]] = float(at)

    def tell(self, t: float, value: object) -> None:
        """News for the other arm (what a diagnosis found of what both share): it hears it
        with the answer to its first claim at `t` or later."""
        self.connection.send(("tell", float(t), value))
        self._told(t)

    def heard(self) -> list[tuple[float, object]]:
        """The other arm's news heard since last asked, (time told, value), in order."""
        out, self.news = self.news, []
        return out

    def unread(self) -> list[tuple[float, object]]:
        """The news :meth:`heard` would give now, left to it."""
        return list(self.news)

    def told(self, kind: str) -> float | None:
        """When the other arm last told news of `kind` ({"kind": ...}) that this arm has
        heard, read or not (None: none heard)."""
        return self._kinds.get(kind)
