"""Value types of the Scanning Laser Ranging Assembly (SLRA): its scan and one range frame.

Shared by the simulator (which makes frames) and Vision (which measures in them); neither
side's knowledge is in here.  Units: metres, radians unless a name says `_deg`.

Scan geometry.  The SLRA steers one amplitude-modulated laser beam with two mirrors over a
rectangular angular window of `fov_deg` (horizontal, vertical) centred on its view axis, at
`shape` (rows, cols) pixels.  Its sensor frame is the tool's TCP frame: z is the view axis,
image columns run along +x and image rows along -y (row 0 at the top, where roll 0 puts
world up).  Pixel (row, col) looks along azimuth a = (col + 0.5 - W/2) * fov_h / W and
elevation e = (row + 0.5 - H/2) * fov_v / H, i.e. along unit(tan a, -tan e, 1); fractional
(row, col) are the continuous scan angles, so edge positions can be sub-pixel.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]
SPEED_OF_LIGHT = 299_792_458.0


@dataclass(frozen=True)
class ScanGeometry:
    """The raster of one frame: pixel count (rows, cols), angular window, modulation.

    fov_deg: (horizontal, vertical) full window, at most the tool's field of view;
    modulation_hz: the AM carrier whose phase gives range (ambiguity interval c / 2f).
    """

    shape: tuple[int, int] = (256, 256)
    fov_deg: tuple[float, float] = (30.0, 24.0)
    modulation_hz: float = 50e6

    def __post_init__(self) -> None:
        if min(self.shape) < 2 or not all(0 < f < 170 for f in self.fov_deg) or self.modulation_hz <= 0:
            raise ValueError(f"bad scan geometry {self.shape}, {self.fov_deg} deg, {self.modulation_hz} Hz")

    @property
    def ambiguity_m(self) -> float:
        """Range ambiguity interval c / (2 f_mod) (m): ranges wrap around modulo this."""
        return SPEED_OF_LIGHT / (2.0 * self.modulation_hz)

    @property
    def pitch_rad(self) -> tuple[float, float]:
        """Angular step between pixels (along a row, along a column) (rad)."""
        h, w = self.shape
        return math.radians(self.fov_deg[0]) / w, math.radians(self.fov_deg[1]) / h

    def angles(self, rows: ArrayLike, cols: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Azimuth and elevation (rad) of fractional pixel coordinates (same shapes)."""
        h, w = self.shape
        da, de = self.pitch_rad
        az = (np.asarray(cols, dtype=float) + 0.5 - w / 2) * da
        el = (np.asarray(rows, dtype=float) + 0.5 - h / 2) * de
        return az, el

    def directions_at(self, rows: ArrayLike, cols: ArrayLike) -> FloatArray:
        """Unit view directions (..., 3) in the sensor frame at fractional pixels (...)."""
        az, el = self.angles(rows, cols)
        d = np.stack([np.tan(az), -np.tan(el), np.ones_like(az)], axis=-1)
        return d / np.linalg.norm(d, axis=-1, keepdims=True)

    def directions(self) -> FloatArray:
        """Unit view directions (H, W, 3) of every pixel centre, sensor frame (read-only:
        made once per geometry, as Vision views every frame of a group once per member)."""
        return _directions(self)

    def pixel_of(self, points: ArrayLike) -> FloatArray:
        """Fractional (row, col) (n, 2) where sensor-frame points (n, 3) appear; nan behind."""
        p = np.atleast_2d(np.asarray(points, dtype=float))
        h, w = self.shape
        da, de = self.pitch_rad
        with np.errstate(divide="ignore", invalid="ignore"):
            az = np.arctan(p[:, 0] / p[:, 2])
            el = np.arctan(-p[:, 1] / p[:, 2])
        rc = np.column_stack([el / de + h / 2 - 0.5, az / da + w / 2 - 0.5])
        rc[p[:, 2] <= 0] = np.nan
        return rc

    def contains(self, rc: ArrayLike, margin: float = 0.0) -> NDArray[np.bool_]:
        """Whether fractional pixels (n, 2) lie inside the raster, `margin` pixels in."""
        rc = np.atleast_2d(np.asarray(rc, dtype=float))
        h, w = self.shape
        with np.errstate(invalid="ignore"):
            return ((rc[:, 0] >= margin - 0.5) & (rc[:, 0] <= h - 0.5 - margin)
                    & (rc[:, 1] >= margin - 0.5) & (rc[:, 1] <= w - 0.5 - margin))


def _frozen(a: ArrayLike) -> FloatArray:
    out = np.array(a, dtype=float)
    out.setflags(write=False)
    return out


@dataclass(frozen=True, eq=False)
class RangeFrame:
    """One SLRA frame: a range image, an intensity image beside it, and where it was taken.

    range_m: (H, W) float, measured (wrapped) range along each pixel's ray, nan where the
    return dropped out; intensity: (H, W) float, return amplitude (1 = a white diffuse
    target square on at the reference range), 0 where nothing came back; pose: (4, 4)
    world pose of the sensor frame as the robot REPORTS it (the commanded pose, not the
    true one); geometry: the scan; timestamp: simulated time at the frame's start (s);
    frame_time: how long the scan took (s); sensor: the tool's name.
    """

    range_m: FloatArray
    intensity: FloatArray
    pose: FloatArray
    geometry: ScanGeometry
    timestamp: float = 0.0
    frame_time: float = 0.0
    sensor: str = "slra"
    notes: dict = field(default_factory=dict, compare=False)

    def __post_init__(self) -> None:
        for name in ("range_m", "intensity", "pose"):
            object.__setattr__(self, name, _frozen(getattr(self, name)))
        if self.range_m.shape != self.geometry.shape or self.intensity.shape != self.geometry.shape:
            raise ValueError(f"images {self.range_m.shape}/{self.intensity.shape} do not match "
                             f"the scan {self.geometry.shape}")
        if self.pose.shape != (4, 4):
            raise ValueError(f"pose must be (4, 4), got {self.pose.shape}")

    @property
    def valid(self) -> NDArray[np.bool_]:
        """(H, W) bool: pixels with a range."""
        return np.isfinite(self.range_m)

    def points(self) -> FloatArray:
        """(H, W, 3) float: sensor-frame points (m) of every pixel, nan for dropouts."""
        return self.geometry.directions() * self.range_m[..., None]

    def points_world(self) -> FloatArray:
        """(H, W, 3) float: the points in the world frame through the reported pose (m)."""
        p = self.points()
        return p @ self.pose[:3, :3].T + self.pose[:3, 3]


@functools.lru_cache(maxsize=32)
def _directions(geometry: ScanGeometry) -> FloatArray:
    """:meth:`ScanGeometry.directions`, computed (a pure function of the geometry)."""
    h, w = geometry.shape
    rows, cols = np.meshgrid(np.arange(h, dtype=float), np.arange(w, dtype=float), indexing="ij")
    d = geometry.directions_at(rows, cols)
    d.setflags(write=False)
    return d


def rotate_directions(d: FloatArray, rotation: FloatArray) -> FloatArray:
    """Directions d (..., 3) turned by the rotation (3, 3): rotation @ each, in a compiled
    loop (a BLAS matmul stalls against embree's threads in the simulator; numpy's
    per-column form makes five temporaries of the whole image)."""
    a = np.ascontiguousarray(d, dtype=np.float64)
    return _rotate_kernel(a.reshape(-1, 3), np.ascontiguousarray(rotation, dtype=np.float64)).reshape(a.shape)


@njit(cache=True)
def _rotate_kernel(d, r):  # pragma: no cover - compiled
    """rotation r (3, 3) @ each row of d (n, 3), each component summed as (x r_k0 + y r_k1) + z r_k2."""
    out = np.empty_like(d)
    for i in range(d.shape[0]):
        x, y, z = d[i, 0], d[i, 1], d[i, 2]
        for k in range(3):
            out[i, k] = x * r[k, 0] + y * r[k, 1] + z * r[k, 2]
    return out
