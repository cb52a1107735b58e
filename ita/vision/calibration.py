"""The SLRA's calibration on reference workpieces: bias corrections and uncertainties of
Vision's sizes, as ISO 15530-3 determines a CMM's task-specific uncertainty with
calibrated workpieces.

    cal = SlraCalibration.load(path)        # bulkhead/slra_calibration.json (the cell's SLRA)
    result = cal.apply(result, feature)     # a VisionResult of a calibrated kind, corrected

Why.  A size measured in one range frame (a hole's diameter, an edge distance, a flange or
rib width) carries errors that do not average away within the frame: the sub-pixel edge
model's bias, the mixed pixels where other surfaces lie beyond a rim, the scanner.  Sized
from first principles they are guesses (type B); measured on workpieces whose dimensions
are known they are figures.  The study (`bench/slra_calibration.py`) measures reference
workpieces (generated bulkheads of other seeds, `ita part new`, whose as-built dimensions
are their calibration certificate) the way a run does, with the arm's pose error, and for
each class of measurement finds the mean error (the bias) and the scatter of the errors
between features.

Applied to a result of class C: value - bias(C), and U the larger of the study's coverage
interval and the frame's own: U_C = the percentile of |error - bias| over the study's
frames that covers 95 % of them with 90 % confidence given the number of features studied
(:func:`coverage_level`; the coverage interval taken from the errors' own distribution, as
GUM Supplement 1 does, since they are not normal: a few features of a class sit far out,
and a tolerance bound, since a study is finite), combined with
the bias's own uncertainty (scatter / sqrt(features)) and the references' certificate; and
2 u_frame, where u_frame is the frame's own random part (the fits of the edges and rims it
saw: :data:`RANDOM_TERMS` of the budget), which the study's frames already carry but which
a troubled frame has more of.  The type-B terms the measurer had (edge model, scanner
angle scale, rim model) are replaced: the study measured what they stood for.  u = U / 2
(k = 2).

Classes (:func:`class_of`): a hole's diameter by its size and what its rim shows (a small
hole with a clear rim; a small hole with other surfaces beyond its rim, a rib under it or a
through hole over the fixture; a large hole, whose rim is seen tilted), an edge distance,
a flange width, a rib width.  A class the calibration does not hold is left as the
measurer made it (its type-B terms), and the result says so.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ita.part.model import Hole
from ita.paths import resource_dir
from ita.specs.model import MeasurementKind as K
from ita.vision.context import FAR_MIXED_SHARE, VisionResult

__all__ = ["CALIBRATED_KINDS", "CALIBRATION_TERM", "CalibrationClass", "LARGE_HOLE_MM", "RANDOM_TERMS",
           "REFERENCE_U_MM", "SlraCalibration", "class_of", "default_path"]

#: the kinds whose results a calibration corrects
CALIBRATED_KINDS = (K.HOLE_DIAMETER, K.EDGE_DISTANCE, K.FLANGE_WIDTH, K.STIFFENER_WIDTH)

#: budget terms that are the frame's own random part (kept; the rest is what the study measured)
RANDOM_TERMS = ("rim fit", "edge line fit", "edge line fits")

#: the budget term a calibration puts in place of the type-B terms
CALIBRATION_TERM = "SLRA calibration (reference workpieces)"

#: a hole this large (diameter, mm) or larger is seen tilted at its rim: a class of its own
LARGE_HOLE_MM = 25.0

#: standard uncertainty (mm) of a reference workpiece's dimensions on its certificate
REFERENCE_U_MM = 0.0005

#: the confidence with which a class's interval covers 95 % of its errors (a finite study)
CONFIDENCE = 0.90


def coverage_level(features: int, coverage: float = 0.95, confidence: float = CONFIDENCE) -> float:
    """The quantile of a study's errors that bounds their `coverage` quantile with
    `confidence`, from `features` independent features: the k-th of them in order, k the
    least with P(Binomial(features, coverage) < k) >= confidence (a distribution-free
    tolerance bound, ISO 16269-6), as a share of them (1 when there are too few)."""
    from scipy.stats import binom

    if features < 1:
        return 1.0
    k = int(binom.ppf(confidence, features, coverage)) + 1
    return min(1.0, k / features)


def default_path() -> Path:
    """The cell's SLRA calibration: bulkhead/slra_calibration.json."""
    return resource_dir("bulkhead") / "slra_calibration.json"


def class_of(kind: K, feature: Any, diagnostics: Mapping[str, Any]) -> str | None:
    """The calibration class of a result of `kind` on `feature` (None: not calibrated)."""
    if kind not in CALIBRATED_KINDS:
        return None
    if kind is K.HOLE_DIAMETER:
        if not isinstance(feature, Hole):
            return None
        if feature.diameter >= LARGE_HOLE_MM:
            return "hole_diameter/large"
        beyond = float(diagnostics.get("far_other_share", 0.0)) > FAR_MIXED_SHARE
        return "hole_diameter/small, surfaces beyond" if beyond else "hole_diameter/small, clear rim"
    return kind.value


def spec_class(spec_id: str) -> str:
    """The class of one spec of a part calibrated on its own master (ita.offline.master)."""
    return f"spec/{spec_id}"


@dataclass(frozen=True)
class CalibrationClass:
    """One class of the study: frames measured and distinct features; bias (mm, mean
    error); scatter (mm, sd of the errors); u_frame_rms (mm, rms of the frames' own random
    part, for the record); u (mm, half the class's coverage interval U_C, see the module
    doc)."""

    name: str
    frames: int
    features: int
    bias: float
    scatter: float
    u_frame_rms: float
    u: float

    @classmethod
    def from_errors(cls, name: str, errors: list[float], u_frames: list[float], features: int) -> CalibrationClass:
        """A class from the errors (measured - reference) of its frames and their own random
        parts (both mm) over `features` distinct features."""
        n = len(errors)
        bias = sum(errors) / n
        scatter = math.sqrt(sum((e - bias) ** 2 for e in errors) / (n - 1)) if n > 1 else 0.0
        rms = math.sqrt(sum(u * u for u in u_frames) / len(u_frames)) if u_frames else 0.0
        q95 = float(np.quantile(np.abs(np.asarray(errors) - bias), coverage_level(features))) if n else 0.0
        u = math.sqrt((q95 / 2) ** 2 + scatter ** 2 / max(features, 1) + REFERENCE_U_MM ** 2)
        return cls(name, n, features, bias, scatter, rms, u)

    def to_dict(self) -> dict[str, Any]:
        return {"frames": self.frames, "features": self.features, "bias_mm": self.bias, "scatter_mm": self.scatter,
                "u_frame_rms_mm": self.u_frame_rms, "u_mm": self.u}


@dataclass(frozen=True)
class SlraCalibration:
    """The classes of a study (name -> CalibrationClass) and where it came from."""

    classes: Mapping[str, CalibrationClass] = field(default_factory=dict)
    provenance: Mapping[str, Any] = field(default_factory=dict)

    @classmethod
    def load(cls, path: Path | None = None) -> SlraCalibration:
        """The calibration in `path` (default: the cell's); none when the file is missing."""
        path = default_path() if path is None else Path(path)
        if not path.is_file():
            return cls()
        data = json.loads(path.read_text(encoding="utf-8"))
        classes = {name: CalibrationClass(name, int(c["frames"]), int(c["features"]), float(c["bias_mm"]),
                                          float(c["scatter_mm"]), float(c["u_frame_rms_mm"]), float(c["u_mm"]))
                   for name, c in data.get("classes", {}).items()}
        return cls(classes, {k: v for k, v in data.items() if k != "classes"})

    def to_dict(self) -> dict[str, Any]:
        return {**self.provenance, "classes": {n: c.to_dict() for n, c in sorted(self.classes.items())}}

    def apply(self, result: VisionResult, feature: Any) -> VisionResult:
        """`result` corrected by its class's bias, its uncertainty the frame's random part
        and the class's u (see the module doc); unchanged when no class holds it."""
        diag = dict(result.diagnostics)
        own = spec_class(result.spec_id)
        name = own if own in self.classes and result.kind in CALIBRATED_KINDS else class_of(result.kind, feature, diag)
        if name is None:
            return result
        c = self.classes.get(name)
        diag["calibration_class"] = name
        if c is None:
            diag["calibration"] = "none (type-B terms)"
            return replace(result, diagnostics=diag)
        budget = dict(diag.get("budget", {}))
        u_frame = math.sqrt(sum(float(budget[t]) ** 2 for t in RANDOM_TERMS if t in budget))
        new_budget = {"the frame's own fits": u_frame, CALIBRATION_TERM: c.u}
        diag.update(budget=new_budget, budget_type_b=budget, budget_rule="the larger term",
                    calibration=f"{name}: bias {1000 * c.bias:+.1f} um corrected, u {1000 * c.u:.1f} um "
                                f"({c.features} features)", correction=-c.bias)
        return replace(result, value=result.value - c.bias, uncertainty=max(u_frame, c.u), diagnostics=diag)
