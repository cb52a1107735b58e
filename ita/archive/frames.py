"""Range frames as the archive keeps them: small enough to keep one per SLRA plan.

    stored = StoredFrame.of(frame, spec_id="HD-OF-017", n=0)     # from a RangeFrame-like value
    meta, rng, inten = encode(stored)                           # the row's columns
    again = decode("HD-OF-017", 0, meta, rng, inten)

Range is kept as uint16 steps of RANGE_STEP_M (0.1 mm: 6.5 m fit, finer than the sensor's
noise), 65535 for a dropout, its high and low bytes in two planes (which compress far
better than interleaved); intensity as 64 levels of its share of the frame's largest
return; both zlib-compressed (level 1: fast).  A 256 x 256 frame takes about 60 KB.  The
archive does not depend on the sensor's types: anything with range_m, intensity, pose,
geometry (shape, fov_deg), timestamp, frame_time and sensor can be stored.
"""

from __future__ import annotations

import json
import zlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

RANGE_STEP_M = 1e-4
INTENSITY_LEVELS = 63
DROPOUT = 65535
#: zlib level 1: about 8 % larger than level 9, about 80 times faster (9 took 0.15 to 0.2 s a frame,
#: a large share of a run's wall time; measured on stored frames of a run)
ZLIB_LEVEL = 1


@dataclass(frozen=True, eq=False)
class StoredFrame:
    """One range frame of a measurement's plan, as stored.

    spec_id: the measurement whose plan took it; n: 0 for the view's own raster, then the
    re-approaches; range_m (H, W) float (nan: dropout); intensity (H, W) float 0..1;
    pose (4, 4) world pose of the sensor as reported; fov_deg (horizontal, vertical);
    meta: the rest (timestamp, frame_time, sensor, frames in the scan, ...).
    """

    spec_id: str
    n: int
    range_m: NDArray[np.float64]
    intensity: NDArray[np.float64]
    pose: NDArray[np.float64]
    fov_deg: tuple[float, float]
    meta: Mapping[str, Any] = field(default_factory=dict)

    @property
    def shape(self) -> tuple[int, int]:
        return (int(self.range_m.shape[0]), int(self.range_m.shape[1]))

    @classmethod
    def of(cls, frame: Any, spec_id: str, n: int = 0, **extra: Any) -> StoredFrame:
        """From a RangeFrame-like value (see the module docstring)."""
        geometry = frame.geometry
        meta = {"timestamp": float(getattr(frame, "timestamp", 0.0)),
                "frame_time": float(getattr(frame, "frame_time", 0.0)),
                "sensor": str(getattr(frame, "sensor", "slra"))} | extra
        return cls(spec_id, int(n), np.asarray(frame.range_m, dtype=float), np.asarray(frame.intensity, dtype=float),
                   np.asarray(frame.pose, dtype=float), (float(geometry.fov_deg[0]), float(geometry.fov_deg[1])),
                   meta)


def encode(frame: StoredFrame) -> tuple[str, bytes, bytes]:
    """(meta JSON, range blob, intensity blob) of `frame`."""
    r = np.asarray(frame.range_m, dtype=float)
    steps = np.full(r.shape, DROPOUT, dtype="<u2")
    ok = np.isfinite(r) & (r >= 0)
    steps[ok] = np.clip(np.rint(r[ok] / RANGE_STEP_M), 0, DROPOUT - 1).astype("<u2")
    inten = np.nan_to_num(np.asarray(frame.intensity, dtype=float), nan=0.0)
    top = float(inten.max()) if inten.size and inten.max() > 0 else 1.0
    bytes8 = np.clip(np.rint(inten / top * INTENSITY_LEVELS), 0, INTENSITY_LEVELS).astype(np.uint8)
    meta = dict(frame.meta) | {"rows": frame.shape[0], "cols": frame.shape[1], "fov_deg": list(frame.fov_deg),
                               "pose": np.asarray(frame.pose, dtype=float).round(9).tolist(),
                               "range_step_m": RANGE_STEP_M, "intensity_max": top,
                               "intensity_levels": INTENSITY_LEVELS}
    planes = steps.view(np.uint8).reshape(-1, 2).T.copy()      # low bytes, then high bytes
    return (json.dumps(meta, sort_keys=True), zlib.compress(planes.tobytes(), ZLIB_LEVEL), zlib.compress(bytes8.tobytes(), ZLIB_LEVEL))


def decode(spec_id: str, n: int, meta_json: str, range_blob: bytes, intensity_blob: bytes) -> StoredFrame:
    """The StoredFrame of one row of the frames table."""
    meta = json.loads(meta_json)
    shape = (int(meta["rows"]), int(meta["cols"]))
    planes = np.frombuffer(zlib.decompress(range_blob), dtype=np.uint8).reshape(2, -1)
    steps = np.ascontiguousarray(planes.T).view("<u2").reshape(shape)
    r = steps.astype(float) * float(meta.get("range_step_m", RANGE_STEP_M))
    r[steps == DROPOUT] = np.nan
    inten = np.frombuffer(zlib.decompress(intensity_blob), dtype=np.uint8).reshape(shape).astype(float)
    inten *= float(meta.get("intensity_max", 1.0)) / float(meta.get("intensity_levels", INTENSITY_LEVELS))
    rest = {k: v for k, v in meta.items() if k not in ("rows", "cols", "fov_deg", "pose")}
    return StoredFrame(spec_id, int(n), r, inten, np.asarray(meta["pose"], dtype=float),
                       (float(meta["fov_deg"][0]), float(meta["fov_deg"][1])), rest)
