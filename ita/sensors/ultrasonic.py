"""The ultrasonic thickness gauge, as the measuring code sees it.

    gauge = UltrasonicGauge(device)          # device: a GaugeDevice (the simulator's, or a real one)
    gauge.apply_couplant()                   # from the approach point, before contact
    reply = gauge.measure()                  # a Reading or a GaugeException, never a made-up value
    ita.archive.decide(reply.thickness_mm, reply.expanded_uncertainty, spec.low_limit, spec.high_limit)

Wire level: the gauge box answers each pulse with a `RawEcho` (status word, thickness,
echo amplitude, dwell).  `interpret` checks it and turns it into a `Reading` or an
exception reply; a reply whose values are out of their domain (a corrupt line, an
unknown status, NaN, a thickness outside the gauge's range, an amplitude outside 0..1)
is GARBAGE.  The gauge reports what it observes, not why: a dead probe, no couplant and
a tilted probe all mean the back-wall echo is missing, and the Exception Handler must
find the cause by tests (a cal-block reading, fresh couplant, a re-approach).

Uncertainty: a Reading's standard uncertainty comes from the gauge's data sheet and
calibration certificate (`GaugeSpec`), never from the part: the calibrated sound
velocity's relative uncertainty, the stated repeatability and the display resolution,
combined in quadrature; U = k u (k = 2) is what the ISO 14253-1 decision
(ita.archive.decide) shrinks and grows the tolerance by.

Velocity calibration: a reading of the calibration block's step (its thickness known to
its certificate) sets the sound velocity for the probe that read it, as an operator sets a
gauge on a step block before use (`velocity_calibration`, `UltrasonicGauge.calibrate`).
Later readings of that probe are scaled by block / reading, and the velocity term of their
uncertainty is the calibration's own (the block reading's repeatability and resolution and
the block's certificate over its thickness: about 0.02 % instead of the data sheet's
0.15 %).  A block reading more than :data:`CAL_ACCEPT_REL` off the block (a doubled echo, a
worn probe) sets nothing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from enum import Enum
from typing import Protocol

STATUS_OK = "ok"
STATUS_NO_PROBE = "no_probe"
STATUS_NO_CONTACT = "no_contact"
STATUS_TILT = "tilt"
STATUS_NO_COUPLING = "no_coupling"
STATUS_NO_SIGNAL = "no_signal"


class GaugeFailure(str, Enum):
    """Why a pulse gave no reading.  The value is the spelling in logs and Prolog."""

    NO_PROBE = "no_probe"          # no ultrasonic probe on the flange (no probe ID on the connector)
    NO_CONTACT = "no_contact"      # the spring-loaded holder's contact switch is open
    MISALIGNED = "misaligned"      # the probe face is tilted beyond the limit: the echo walks off
    NO_COUPLANT = "no_couplant"    # only the probe-face echo: sound does not enter the part
    NO_ECHO = "no_echo"            # no echo at all (dead element) or no back wall in range
    GARBAGE = "garbage"            # the reply makes no sense
    DOUBLED = "doubled"            # (from `check_expected`) about twice the expected value
    IMPLAUSIBLE = "implausible"    # (the gauge device) far outside what the part makes plausible

    @property
    def no_echo(self) -> bool:
        """Whether this failure means the gauge saw no back-wall echo."""
        return self in (GaugeFailure.MISALIGNED, GaugeFailure.NO_COUPLANT, GaugeFailure.NO_ECHO)


_STATUS_FAILURES = {
    STATUS_NO_PROBE: GaugeFailure.NO_PROBE,
    STATUS_NO_CONTACT: GaugeFailure.NO_CONTACT,
    STATUS_TILT: GaugeFailure.MISALIGNED,
    STATUS_NO_COUPLING: GaugeFailure.NO_COUPLANT,
    STATUS_NO_SIGNAL: GaugeFailure.NO_ECHO,
}


@dataclass(frozen=True)
class RawEcho:
    """One reply line of the gauge box: status word, thickness (mm), echo amplitude
    (0..1 of full scale), the time the pulse took (s) and the connected probe's ID."""

    status: str
    thickness_mm: float = math.nan
    amplitude: float = 0.0
    dwell_s: float = 0.0
    probe: str = ""


@dataclass(frozen=True)
class Dispensed:
    """The couplant dispenser's reply: it ran for `dwell_s` (it cannot tell whether any
    couplant came out)."""

    dwell_s: float


class GaugeDevice(Protocol):
    """What a gauge (simulated or real) offers: a pulse, and a squirt of couplant."""

    def pulse(self) -> RawEcho: ...

    def dispense(self) -> Dispensed: ...


@dataclass(frozen=True)
class GaugeSpec:
    """The gauge as its data sheet and calibration certificate state it.

    range_mm: measuring range; resolution_mm: display step; repeatability_sd_mm: stated
    single-reading standard deviation; velocity_u_rel: relative standard uncertainty of
    the calibrated sound velocity (a velocity error scales the reading); min_thickness_mm:
    below this the probe may lock on the second echo and read double; max_tilt_deg: the
    largest probe tilt at which an echo is still seen; min_amplitude: weakest echo the
    gauge accepts; coverage_k: coverage factor for the expanded uncertainty.
    """

    range_mm: tuple[float, float] = (0.5, 100.0)
    resolution_mm: float = 0.001
    repeatability_sd_mm: float = 0.002
    velocity_u_rel: float = 0.0015
    min_thickness_mm: float = 1.0
    max_tilt_deg: float = 4.0
    min_amplitude: float = 0.05
    coverage_k: float = 2.0

    def standard_uncertainty(self, thickness_mm: float, velocity_u_rel: float | None = None) -> float:
        """u (mm) of one reading of `thickness_mm`: velocity (the data sheet's, or
        `velocity_u_rel` after a calibration), repeatability, resolution."""
        rel = self.velocity_u_rel if velocity_u_rel is None else velocity_u_rel
        return math.sqrt((rel * thickness_mm) ** 2 + self.reading_u() ** 2)

    def reading_u(self) -> float:
        """u (mm) of one reading apart from the velocity: repeatability and resolution."""
        return math.sqrt(self.repeatability_sd_mm ** 2 + self.resolution_mm ** 2 / 12.0)


#: a block reading further than this share from the block's thickness calibrates nothing
CAL_ACCEPT_REL = 0.01


@dataclass(frozen=True)
class VelocityCalibration:
    """The sound velocity set on the calibration block with `probe`: a reading of `block_mm`
    gave `reading_mm`; later readings are scaled by :attr:`factor`; u_rel: the relative
    standard uncertainty of that scale; time: simulated time of the block reading (s)."""

    probe: str
    block_mm: float
    reading_mm: float
    u_rel: float
    time: float = 0.0

    @property
    def factor(self) -> float:
        return self.block_mm / self.reading_mm


def velocity_calibration(reading: Reading, block_mm: float, block_u_mm: float, spec: GaugeSpec,
                         time: float = 0.0) -> VelocityCalibration | None:
    """The calibration a block reading gives (None: the reading is more than
    CAL_ACCEPT_REL off the block, so it calibrates nothing)."""
    if not (block_mm > 0 and abs(reading.thickness_mm / block_mm - 1.0) <= CAL_ACCEPT_REL):
        return None
    u_rel = math.hypot(spec.reading_u(), block_u_mm) / block_mm
    return VelocityCalibration(reading.probe, float(block_mm), float(reading.thickness_mm), u_rel, float(time))


@dataclass(frozen=True)
class Reading:
    """A thickness reading: value and standard uncertainty (mm), echo amplitude (0..1),
    the time it took (s), the probe that took it, the coverage factor of U and the
    velocity calibration's scale applied to it."""

    thickness_mm: float
    u_mm: float
    amplitude: float
    dwell_s: float
    probe: str
    coverage_k: float = 2.0
    velocity_factor: float = 1.0    # the scale a velocity calibration applied (1: none)

    @property
    def expanded_uncertainty(self) -> float:
        """U = k u (mm)."""
        return self.coverage_k * self.u_mm


@dataclass(frozen=True)
class GaugeException:
    """An exception reply of the gauge (a value, not a raised exception): the reason, the
    time the attempt took (s) and one line for people."""

    reason: GaugeFailure
    dwell_s: float = 0.0
    message: str = ""

    @property
    def no_echo(self) -> bool:
        """Whether the back-wall echo was missing (see GaugeFailure.no_echo)."""
        return self.reason.no_echo


GaugeReply = Reading | GaugeException


def interpret(raw: object, spec: GaugeSpec) -> GaugeReply:
    """A Reading or an exception reply from one raw gauge reply (see the module doc)."""
    if not isinstance(raw, RawEcho):
        return GaugeException(GaugeFailure.GARBAGE, 0.0, f"unreadable reply {raw!r}")
    dwell = raw.dwell_s if _finite(raw.dwell_s) and raw.dwell_s >= 0.0 else 0.0
    if raw.status in _STATUS_FAILURES:
        reason = _STATUS_FAILURES[raw.status]
        return GaugeException(reason, dwell, f"gauge reports {raw.status}")
    if raw.status != STATUS_OK:
        return GaugeException(GaugeFailure.GARBAGE, dwell, f"unknown status {raw.status!r}")
    t, a = raw.thickness_mm, raw.amplitude
    lo, hi = spec.range_mm
    if not (_finite(t) and _finite(a)) or not lo <= t <= hi or not 0.0 <= a <= 1.0 or dwell != raw.dwell_s:
        return GaugeException(GaugeFailure.GARBAGE, dwell, f"values out of domain: t={t!r} mm, amplitude={a!r}")
    if a < spec.min_amplitude:
        return GaugeException(GaugeFailure.NO_ECHO, dwell, f"echo amplitude {a:.3f} below {spec.min_amplitude}")
    return Reading(float(t), spec.standard_uncertainty(t), float(a), float(dwell), raw.probe, spec.coverage_k)


def check_expected(reply: GaugeReply, expected_mm: float, tolerance_mm: float) -> GaugeReply:
    """A reading about twice `expected_mm` (within 10 tolerances of 2x) becomes a DOUBLED
    exception reply (second-echo lock: thin section or worn probe); anything else passes."""
    if isinstance(reply, Reading) and abs(reply.thickness_mm - 2.0 * expected_mm) <= 10.0 * tolerance_mm:
        return GaugeException(GaugeFailure.DOUBLED, reply.dwell_s,
                              f"reads {reply.thickness_mm:.3f} mm, twice the expected {expected_mm:.3f} mm")
    return reply


class UltrasonicGauge:
    """The gauge facade: couplant and readings through a GaugeDevice."""

    def __init__(self, device: GaugeDevice, spec: GaugeSpec = GaugeSpec()) -> None:
        self.device = device
        self.spec = spec
        self.calibrations: dict[str, VelocityCalibration] = {}

    def calibrate(self, calibration: VelocityCalibration) -> None:
        """Set the sound velocity for the calibration's probe (replaces an earlier one)."""
        self.calibrations[calibration.probe] = calibration

    def apply_couplant(self) -> Dispensed:
        """Squirt couplant along the probe's axis onto the surface ahead of it."""
        return self.device.dispense()

    def measure(self) -> GaugeReply:
        """One pulse: a Reading (scaled by its probe's velocity calibration, if any) or a
        GaugeException."""
        reply = interpret(self.device.pulse(), self.spec)
        cal = self.calibrations.get(reply.probe) if isinstance(reply, Reading) else None
        if cal is None or not isinstance(reply, Reading):
            return reply
        t = reply.thickness_mm * cal.factor
        return replace(reply, thickness_mm=t, u_mm=self.spec.standard_uncertainty(t, cal.u_rel),
                       velocity_factor=cal.factor)


def _finite(x: object) -> bool:
    return isinstance(x, (int, float)) and math.isfinite(x)
