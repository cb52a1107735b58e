"""Each serial number its own as-built part of one design (a generated part's).

A plant makes the same design again and again; what varies from part to part is the
process's spread.  In simulation a serial's as-built part is drawn from the design's
nominal features with the generator's spread (``[truth] spread`` of the parameters), seeded
by the serial number, so that the same serial is the same part every time and two serials
are two parts.  A process in control makes no gross errors: none of a serial's features is
pushed out of tolerance (the generator's ``out_of_tolerance`` share is the first article's,
not a production part's).  A special cause is asked for on purpose: a *shift* moves one
characteristic's feature dimension by DELTA mm in that serial (``ita inspect --serial SN
--shift SPEC=DELTA``), which is how SPC's detection is checked.

    asbuilt = serial_asbuilt(part, "SN-0042", {"WT-P01-1": 0.10})
    asbuilt.directory         # <part>/serials/<key>: truth/ (mesh, features, values) + serial.json

The truth is written once per (serial, shifts) and reused.  Only generated parts (the
built-in bulkhead, `ita part new` with the built-in parameters) have the parameters at hand;
any other part keeps its one as-built (InputError for --shift).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import shutil
import uuid
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ita.errors import InputError, Location
from ita.part import truth as truth_mod
from ita.part.bulkhead import default_params_path, load_params
from ita.part.mesh import build_mesh
from ita.part.model import FlangeSegment, Hole, Part, Pocket, Stiffener
from ita.part.params import BulkheadParams
from ita.part.store import fingerprint
from ita.specs.io import read_specs
from ita.specs.model import MeasurementKind as K

__all__ = ["SERIALS_DIR", "SerialAsBuilt", "design_params", "parse_shift", "serial_asbuilt", "serial_seed"]

#: where a part's serials' as-built parts are kept (under its directory)
SERIALS_DIR = "serials"
SERIAL_FILE = "serial.json"


@dataclass(frozen=True)
class SerialAsBuilt:
    """A serial's as-built part: its directory (holding truth/), the serial, the seed of its
    draw and the shifts asked (spec id -> mm)."""

    directory: Path
    serial: str
    seed: int
    shifts: Mapping[str, float]

    def describe(self) -> str:
        shifts = ", ".join(f"{k} {v:+g} mm" for k, v in sorted(self.shifts.items()))
        return f"serial {self.serial}'s as-built part (seed {self.seed}" + (f"; shifted: {shifts})" if shifts else ")")


def serial_seed(serial: str) -> int:
    """The seed of a serial's as-built draw: from its SHA-256 (the same serial, the same part)."""
    return int.from_bytes(hashlib.sha256(serial.encode("utf-8")).digest()[:8], "big")


def parse_shift(text: str) -> tuple[str, float]:
    """``SPEC=DELTA`` (mm, signed) -> (spec id, delta); InputError naming the option."""
    spec, sep, value = text.partition("=")
    try:
        delta = float(value)
    except ValueError:
        delta = math.nan
    if not sep or not spec.strip() or not math.isfinite(delta):
        raise InputError([(Location("--shift"), f"{text!r}: give SPEC=DELTA, a spec id and a shift in mm "
                                                "(e.g. WT-P01-1=0.1)")])
    return spec.strip(), delta


def design_params(part: Part) -> BulkheadParams | None:
    """The generator's parameters of a generated part when they are at hand (the built-in
    parameters, with the part's seed), else None."""
    meta_path = part.directory / "part.json"
    try:
        meta = json.loads(meta_path.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(meta, dict) or meta.get("generator") != "ita.part.bulkhead":
        return None
    params = load_params()
    fp = fingerprint(default_params_path())
    seed = int(meta.get("seed", params.part.seed))
    known = {fp, hashlib.sha256(f"{fp} seed={seed}".encode()).hexdigest()}
    if meta.get("fingerprint") not in known:
        return None
    return replace(params, part=replace(params.part, seed=seed))


def _shift_feature(devs: dict[str, dict[str, float]], features: Mapping[str, object], spec_kind: K,
                   normal_z: float, feature_id: str, delta: float, spec_id: str) -> None:
    """Add `delta` to the feature dimension a spec of `spec_kind` measures."""
    f = features.get(feature_id)
    if spec_kind is K.WEB_THICKNESS and isinstance(f, Pocket):
        dim = "web_thickness"
    elif spec_kind is K.FLANGE_THICKNESS and isinstance(f, FlangeSegment):
        dim = "cap_thickness" if normal_z > 0.5 else "wall_thickness"
    elif spec_kind in (K.FLANGE_HEIGHT, K.STIFFENER_HEIGHT) and isinstance(f, (FlangeSegment, Stiffener)):
        dim = "height"
    elif spec_kind is K.FLANGE_WIDTH and isinstance(f, FlangeSegment):
        dim = "cap_width"
    elif spec_kind is K.STIFFENER_WIDTH and isinstance(f, Stiffener):
        dim = "width"
    elif spec_kind is K.HOLE_DIAMETER and isinstance(f, Hole):
        dim = "diameter"
    elif spec_kind is K.HOLE_POSITION and isinstance(f, Hole):
        dim = "dx"            # the position value is 2 |d|: a shift of DELTA along x moves it by about DELTA
        delta = delta / 2
    else:
        raise InputError([(Location("--shift"), f"{spec_id}: a {spec_kind.value} cannot be shifted "
                                                "(thicknesses, heights, widths, diameters and positions can)")])
    d = devs.setdefault(feature_id, {})
    d[dim] = d.get(dim, 0.0) + delta


def serial_asbuilt(part: Part, serial: str, shifts: Mapping[str, float] | None = None) -> SerialAsBuilt:
    """The as-built part of `serial` of the generated `part` (made and kept the first time;
    see the module docstring).  InputError when the part's generator parameters are not at
    hand or a shift names an unknown spec."""
    shifts = dict(sorted((shifts or {}).items()))
    params = design_params(part)
    if params is None:
        raise InputError([(Location(str(part.directory)), "per-serial as-built parts need a generated part's "
                                                          "parameters (the built-in bulkhead or `ita part new`); "
                                                          "this part keeps its one as-built part")])
    specs = {s.id: s for s in read_specs(part.specs_path)}
    unknown = sorted(set(shifts) - set(specs))
    if unknown:
        raise InputError([(Location("--shift"), f"no spec {unknown[0]!r} in {part.specs_path}")])
    seed = serial_seed(serial)
    key = hashlib.sha256(json.dumps([serial, shifts]).encode()).hexdigest()[:20]
    directory = part.directory / SERIALS_DIR / key
    made = SerialAsBuilt(directory, serial, seed, shifts)
    if (directory / SERIAL_FILE).is_file():
        return made
    rng = np.random.default_rng([params.part.seed, 1, seed])
    devs, _ = truth_mod.draw_deviations(part.features, params.tolerance, params.truth.spread, 0.0, rng)
    by_id = {f.id: f for f in part.features}
    for spec_id, delta in shifts.items():
        s = specs[spec_id]
        _shift_feature(devs, by_id, s.kind, s.normal[2], s.feature, delta, spec_id)
    asbuilt = truth_mod.apply_deviations(part.features, devs)
    values = truth_mod.true_values(list(specs.values()), part.features, asbuilt)
    made_truth = truth_mod.Truth(asbuilt, build_mesh(asbuilt), values, devs, (), seed)
    tmp = directory.with_name(f".{key}-{uuid.uuid4().hex}")
    tmp.mkdir(parents=True)
    try:
        truth_mod.write_truth(tmp, made_truth)
        (tmp / SERIAL_FILE).write_text(json.dumps({"serial": serial, "seed": seed, "shifts": shifts}, indent=1))
        try:
            os.rename(tmp, directory)
        except OSError:
            if not (directory / SERIAL_FILE).is_file():     # not another process's same part
                raise
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return made
