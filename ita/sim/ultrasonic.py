"""The ultrasonic thickness gauge's physics, on the simulated workcell's AS-BUILT part.

`UltrasonicSim(world)` is a `ita.sensors.ultrasonic.GaugeDevice`: the gauge box and the
probe on the arm.  A pulse looks at the held tool (an ultrasonic probe, or NO_PROBE) and
casts a ray along the probe's tip axis through the as-built mesh, in the part frame
(millimetres, float64, exact triangle tests):

* contact: the probe tip is spring loaded (`travel_mm`).  The tool's TCP is the tip at
  full extension; the probe touches when the first surface the ray enters lies between
  that point and `travel_mm` behind it (an over-travel bumps the tool's shaft into the
  part, which the controller reports).  Otherwise: NO_CONTACT.
* alignment: the angle between the tip axis and the surface normal where it touches must
  stay within `max_tilt_deg`, or the echo walks off: MISALIGNED.
* coupling: a couplant spot (put by `dispense`, still wet) must cover the contact point,
  or only the probe-face echo returns: NO_COUPLANT.
* the thickness is the ray's length inside the material up to the next surface (the back
  wall); none within range: NO_ECHO.  The gauge reports it scaled by the sound-velocity
  calibration error (a systematic relative bias drawn once per world), plus Gaussian
  noise, rounded to the display resolution.  Below `min_thickness_mm`, or with a worn
  probe, the gauge locks on the second back-wall echo and reads double.
* every pulse takes `dwell_s` of simulated time (settling and averaging), a squirt of
  couplant `dispense_s`.

Faults (world.faults): BROKEN_PROBE and WORN_PROBE target a tool name; DRY_COUPLANT the
tool whose dispenser is dry; EMPTY_COUPLANT the couplant station (no dispenser gives any);
SENSOR_GARBAGE targets GAUGE and makes every reply corrupt; TRANSIENT on GAUGE loses the
next echo once; TILTED_PROBE (a probe crooked in its holder) tilts every reading of that
probe, on the part and on the block, past `max_tilt_deg`.

The calibration block: `pulse_reference(thickness_mm)` is a reading of the block (a
known thickness), with the same faults and the same calibration error; the arm's
drift, when larger than the probe's footprint allows, tilts it off the block's face.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import trimesh
from numpy.typing import NDArray

from ita.sensors.ultrasonic import (
    STATUS_NO_CONTACT,
    STATUS_NO_COUPLING,
    STATUS_NO_PROBE,
    STATUS_NO_SIGNAL,
    STATUS_OK,
    STATUS_TILT,
    Dispensed,
    RawEcho,
)
from ita.sim.faults import GAUGE, STATION, Fault
from ita.sim.world import CouplantSpot, SimWorld

FloatArray = NDArray[np.float64]
_LEAD_MM = 30.0             # the ray starts this far before the free tip


@dataclass(frozen=True)
class ProbePhysics:
    """What the simulated gauge and probe really do (the measuring code does not know
    the bias; it knows the GaugeSpec).

    velocity_bias: relative error of the calibrated sound velocity (None: drawn once
    from the world's seed, uniform 0.1 to 0.25 % with a random sign); noise_sd_mm:
    reading noise; resolution_mm: display step; min_thickness_mm: below it a reading
    doubles; max_tilt_deg: echo lost beyond it; travel_mm: the tip's spring travel;
    range_mm: the farthest back wall seen; dwell_s / dispense_s: time per pulse / squirt;
    spot_radius_mm / couplant_life_s: a couplant spot's size and how long it stays wet;
    worn_amplitude: echo amplitude factor of a worn probe.
    """

    velocity_bias: float | None = None
    noise_sd_mm: float = 0.002
    resolution_mm: float = 0.001
    min_thickness_mm: float = 1.0
    max_tilt_deg: float = 4.0
    travel_mm: float = 5.0
    range_mm: float = 100.0
    dwell_s: float = 1.2
    dispense_s: float = 0.4
    spot_radius_mm: float = 6.0
    couplant_life_s: float = 600.0
    worn_amplitude: float = 0.3


@dataclass(frozen=True)
class ProbeContact:
    """Where the probe's axis meets the part (part frame, mm): the contact point, how far
    the tip is pushed in (mm, < 0 = a gap), the tilt (deg) and the thickness along the
    axis (mm; nan when no back wall is within range)."""

    point_mm: tuple[float, float, float]
    pressed_mm: float
    tilt_deg: float
    thickness_mm: float


class TriangleIndex:
    """Exact ray-segment tests against a triangle mesh (float64), with a box prefilter."""

    def __init__(self, mesh: trimesh.Trimesh) -> None:
        tri = np.asarray(mesh.vertices, dtype=float)[np.asarray(mesh.faces)]
        self.v0 = tri[:, 0]
        self.e1 = tri[:, 1] - tri[:, 0]
        self.e2 = tri[:, 2] - tri[:, 0]
        normals = np.cross(self.e1, self.e2)
        norms = np.linalg.norm(normals, axis=1)
        keep = norms > 1e-12                 # degenerate (zero-area) triangles cannot be hit
        self.v0, self.e1, self.e2 = self.v0[keep], self.e1[keep], self.e2[keep]
        self.normals = normals[keep] / norms[keep, None]
        self.lo = tri[keep].min(axis=1)
        self.hi = tri[keep].max(axis=1)

    def hits(self, origin: FloatArray, direction: FloatArray, length: float) -> tuple[FloatArray, FloatArray]:
        """Distances (k,) mm along the unit `direction` from `origin` (3,) to every
        triangle the segment of `length` crosses, ascending, and their normals (k, 3)."""
        o = np.asarray(origin, dtype=float)
        d = np.asarray(direction, dtype=float)
        end = o + length * d
        lo, hi = np.minimum(o, end) - 1e-9, np.maximum(o, end) + 1e-9
        cand = np.flatnonzero(np.all((self.lo <= hi) & (self.hi >= lo), axis=1))
        if cand.size == 0:
            return np.empty(0), np.empty((0, 3))
        e1, e2, v0 = self.e1[cand], self.e2[cand], self.v0[cand]
        pvec = np.cross(d, e2)
        det = np.einsum("ij,ij->i", e1, pvec)
        ok = np.abs(det) > 1e-14
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        tvec = o - v0
        u = np.einsum("ij,ij->i", tvec, pvec) * inv
        qvec = np.cross(tvec, e1)
        v = np.einsum("j,ij->i", d, qvec) * inv
        t = np.einsum("ij,ij->i", e2, qvec) * inv
        eps = 1e-12
        hit = ok & (u >= -eps) & (v >= -eps) & (u + v <= 1 + eps) & (t >= 0.0) & (t <= length)
        order = np.argsort(t[hit])
        ts, ns = t[hit][order], self.normals[cand[hit]][order]
        keep = np.ones(len(ts), dtype=bool)   # one hit where the ray crosses a shared edge
        keep[1:] = ~((np.diff(ts) < 1e-9) & (np.einsum("ij,ij->i", ns[1:], ns[:-1]) > 0.0))
        return ts[keep], ns[keep]


class UltrasonicSim:
    """The simulated gauge and probe on `world`'s arm (a GaugeDevice; see the module doc)."""

    def __init__(self, world: SimWorld, physics: ProbePhysics = ProbePhysics()) -> None:
        self.world = world
        self.physics = physics
        rng = np.random.default_rng([world.seed, 11])
        drawn = float(rng.choice([-1.0, 1.0]) * rng.uniform(0.001, 0.0025))
        self.velocity_bias = drawn if physics.velocity_bias is None else float(physics.velocity_bias)
        self._index = TriangleIndex(world.asbuilt_mesh)
        self._rng = np.random.default_rng([world.seed, 12])
        self.last_dispense_ok = False     # whether the last squirt gave couplant

    # -- the device interface ------------------------------------------------------------
    def pulse(self) -> RawEcho:
        """Fire the probe once (see the module doc); the clock advances by dwell_s."""
        world, ph = self.world, self.physics
        world.clock.advance(ph.dwell_s)
        tool = world.held_tool
        if tool is None or not tool.tool_class.ultrasonic:
            return RawEcho(STATUS_NO_PROBE, dwell_s=ph.dwell_s)
        if world.faults.has(Fault.SENSOR_GARBAGE, GAUGE):
            return self._garbage(tool.name)
        contact = self.contact()

        def echo(status: str) -> RawEcho:
            return RawEcho(status, dwell_s=ph.dwell_s, probe=tool.name)

        if contact is None or contact.pressed_mm < 0.0:
            return echo(STATUS_NO_CONTACT)
        if contact.tilt_deg > ph.max_tilt_deg or world.faults.has(Fault.TILTED_PROBE, tool.name):
            return echo(STATUS_TILT)
        if world.faults.has(Fault.BROKEN_PROBE, tool.name):
            return echo(STATUS_NO_SIGNAL)
        if world.faults.has(Fault.TRANSIENT, GAUGE):
            world.faults = world.faults.without(Fault.TRANSIENT, GAUGE)
            return echo(STATUS_NO_SIGNAL)
        if not self.wet(contact.point_mm):
            return echo(STATUS_NO_COUPLING)
        if not math.isfinite(contact.thickness_mm):
            return echo(STATUS_NO_SIGNAL)
        worn = world.faults.has(Fault.WORN_PROBE, tool.name)
        value = contact.thickness_mm * (1.0 + self.velocity_bias)
        if worn or contact.thickness_mm < ph.min_thickness_mm:
            value *= 2.0
        tilt_factor = max(0.0, math.cos(math.radians(contact.tilt_deg) * 90.0 / ph.max_tilt_deg))
        amplitude = 0.9 * (0.4 + 0.6 * tilt_factor) * math.exp(-0.005 * contact.thickness_mm)
        amplitude *= ph.worn_amplitude if worn else 1.0
        value += self._rng.normal(0.0, ph.noise_sd_mm)
        value = round(value / ph.resolution_mm) * ph.resolution_mm
        return RawEcho(STATUS_OK, float(value), float(amplitude), ph.dwell_s, tool.name)

    def dispense(self) -> Dispensed:
        """Squirt couplant along the probe axis onto the first surface ahead (within 0.2 m)."""
        world, ph = self.world, self.physics
        world.clock.advance(ph.dispense_s)
        tool = world.held_tool
        if tool is None or not tool.tool_class.ultrasonic:
            return Dispensed(ph.dispense_s)
        if world.faults.has(Fault.DRY_COUPLANT, tool.name) or world.faults.has(Fault.EMPTY_COUPLANT, STATION):
            self.last_dispense_ok = False
            return Dispensed(ph.dispense_s)
        self.last_dispense_ok = True
        origin, axis = self._tip_ray()
        dist, normals = self._index.hits(origin, axis, _LEAD_MM + 200.0)
        entering = np.flatnonzero(normals @ axis < 0.0)
        if entering.size:
            point = origin + dist[entering[0]] * axis
            px, py, pz = map(float, point)
            world.add_couplant(CouplantSpot((px, py, pz), ph.spot_radius_mm, world.clock.now))
        return Dispensed(ph.dispense_s)

    def pulse_reference(self, thickness_mm: float, drift_limit_m: float = 1.0e-3) -> RawEcho:
        """A reading of the calibration block (`thickness_mm`), the probe on its face with
        couplant just dispensed (`dispense` first): the held probe's faults, the couplant,
        the calibration error and noise as on the part; an arm drifted more than
        `drift_limit_m` leaves the probe tilted on the block's edge."""
        world, ph = self.world, self.physics
        world.clock.advance(ph.dwell_s)
        tool = world.held_tool
        if tool is None or not tool.tool_class.ultrasonic:
            return RawEcho(STATUS_NO_PROBE, dwell_s=ph.dwell_s)
        if world.faults.has(Fault.SENSOR_GARBAGE, GAUGE):
            return self._garbage(tool.name)

        def echo(status: str) -> RawEcho:
            return RawEcho(status, dwell_s=ph.dwell_s, probe=tool.name)

        if float(np.linalg.norm(world.drift_m)) > drift_limit_m or world.faults.has(Fault.TILTED_PROBE, tool.name):
            return echo(STATUS_TILT)
        if world.faults.has(Fault.BROKEN_PROBE, tool.name):
            return echo(STATUS_NO_SIGNAL)
        if not self.last_dispense_ok:
            return echo(STATUS_NO_COUPLING)
        worn = world.faults.has(Fault.WORN_PROBE, tool.name)
        value = thickness_mm * (1.0 + self.velocity_bias) * (2.0 if worn else 1.0)
        value += self._rng.normal(0.0, ph.noise_sd_mm)
        value = round(value / ph.resolution_mm) * ph.resolution_mm
        amplitude = 0.9 * math.exp(-0.005 * thickness_mm) * (ph.worn_amplitude if worn else 1.0)
        return RawEcho(STATUS_OK, float(value), float(amplitude), ph.dwell_s, tool.name)

    def station_level(self) -> float:
        """The couplant station's level (%): 0 when EMPTY_COUPLANT, else full."""
        return 0.0 if self.world.faults.has(Fault.EMPTY_COUPLANT, STATION) else 100.0

    # -- geometry ------------------------------------------------------------------------
    def contact(self) -> ProbeContact | None:
        """Where the held probe's axis meets the as-built part now (None: nowhere near)."""
        ph = self.physics
        origin, axis = self._tip_ray()
        dist, normals = self._index.hits(origin, axis, _LEAD_MM + ph.travel_mm + ph.range_mm)
        if dist.size == 0:
            return None
        facing = normals @ axis
        if facing[0] >= 0.0:            # the ray starts inside the material: far over-travel
            return None
        entry, normal = dist[0], normals[0]
        tilt = math.degrees(math.acos(min(1.0, float(-normal @ axis))))
        back = dist[1:][(dist[1:] > entry + 1e-9) & (facing[1:] > 0.0)]
        thickness = float(back[0] - entry) if back.size and back[0] - entry <= ph.range_mm else math.nan
        point = origin + entry * axis
        return ProbeContact(tuple(map(float, point)), float(_LEAD_MM - entry), tilt, thickness)  # type: ignore[arg-type]

    def wet(self, point_mm) -> bool:
        """Whether a couplant spot still wet now covers the part point (mm)."""
        world, ph = self.world, self.physics
        if not world.couplant:
            return False
        centres = np.array([s.center_mm for s in world.couplant])
        radii = np.array([s.radius_mm for s in world.couplant])
        ages = world.clock.now - np.array([s.time_s for s in world.couplant])
        near = np.linalg.norm(centres - np.asarray(point_mm, dtype=float), axis=1) <= radii
        return bool(np.any(near & (ages <= ph.couplant_life_s)))

    def _tip_ray(self) -> tuple[FloatArray, FloatArray]:
        """Ray start (part mm, _LEAD_MM before the free tip) and unit tip axis (part frame)."""
        placement = self.world.part_placement
        tcp = self.world.tcp_pose()
        tip = placement.to_part(tcp[:3, 3][None])[0]
        axis = tcp[:3, 2] @ placement.rotation_matrix()
        axis /= np.linalg.norm(axis)
        return tip - _LEAD_MM * axis, axis

    def _garbage(self, probe: str) -> RawEcho:
        """A corrupt reply: one of the ways a bad line or a confused gauge looks."""
        ph = self.physics
        kind = int(self._rng.integers(5))
        if kind == 0:
            return RawEcho(STATUS_OK, math.nan, 0.8, ph.dwell_s, probe)
        if kind == 1:
            return RawEcho(STATUS_OK, -float(self._rng.uniform(0.1, 50.0)), 0.8, ph.dwell_s, probe)
        if kind == 2:
            return RawEcho(STATUS_OK, float(self._rng.uniform(1e3, 1e6)), 0.8, ph.dwell_s, probe)
        if kind == 3:
            return RawEcho(STATUS_OK, 2.5, float(self._rng.uniform(1.5, 99.0)), ph.dwell_s, probe)
        return RawEcho("\x15E#" + str(int(self._rng.integers(100))), 0.0, 0.0, ph.dwell_s, probe)
