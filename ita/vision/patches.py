"""A range frame seen in the part frame, and rectangular patches over parts of it.

`View` puts a frame's pixels into the part frame (mm) through the pose the robot reported
and the nominal part placement: every point, every pixel's ray, and the way back from part
points to (fractional) pixels.  A `Patch` is a rectangle of pixels that covers a region of
the part given by its corner points, with a mask of the pixels that fall in that region.
"""

from __future__ import annotations

import functools
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ita.sensors.slra_frame import RangeFrame, rotate_directions
from ita.workcell.model import PartPlacement

FloatArray = NDArray[np.float64]


class View:
    """Frame `frame` in the part frame of `placement` (mm)."""

    def __init__(self, frame: RangeFrame, placement: PartPlacement):
        self.frame = frame
        self.geometry = frame.geometry
        self.placement = placement
        rot = placement.rotation_matrix()
        self._to_part = rot.T @ frame.pose[:3, :3]                       # sensor -> part
        self._from_part = self._to_part.T
        self.origin = placement.to_part(frame.pose[None, :3, 3])[0]
        self.range_mm = frame.range_m / placement.scale
        self.intensity = frame.intensity
        # mm per pixel on a surface square-on at the nominal range of the frame's centre
        self.pixel_rad = float(np.mean(self.geometry.pitch_rad))
        self.found: dict[Any, Any] = {}   # what measurers found in this view (a rim's fit), by what they asked

    @functools.cached_property
    def dirs(self) -> FloatArray:
        """Unit part-frame rays (H, W, 3) of every pixel (made when first asked for)."""
        return rotate_directions(self.geometry.directions(), self._to_part)

    @functools.cached_property
    def points(self) -> FloatArray:
        """Part points (H, W, 3) mm of every pixel's range (nan where it has none)."""
        return self.origin + self.dirs * self.range_mm[..., None]

    @property
    def shape(self) -> tuple[int, int]:
        return self.geometry.shape

    def pixel_of(self, pts: FloatArray) -> FloatArray:
        """Fractional (row, col) (n, 2) of part points (n, 3) mm."""
        p = (np.atleast_2d(pts) - self.origin) @ self._from_part.T
        return self.geometry.pixel_of(p)

    def rays_at(self, rc: FloatArray) -> FloatArray:
        """Unit part-frame rays (n, 3) at fractional pixels (n, 2)."""
        rc = np.atleast_2d(rc)
        return self.geometry.directions_at(rc[:, 0], rc[:, 1]) @ self._to_part.T

    def pixel_mm(self, distance_mm: float) -> float:
        """Size (mm) of one pixel at `distance_mm` from the sensor."""
        return distance_mm * self.pixel_rad

    def plane_range(self, coef: tuple[float, float, float], dirs: FloatArray) -> FloatArray:
        """Range (...) mm along part rays dirs (..., 3) from the sensor to z = a x + b y + c."""
        a, b, c = coef
        o = self.origin
        with np.errstate(divide="ignore", invalid="ignore"):
            return (a * o[0] + b * o[1] + c - o[2]) / (dirs[..., 2] - a * dirs[..., 0] - b * dirs[..., 1])

    def on_plane(self, rc: FloatArray, coef: tuple[float, float, float]) -> FloatArray:
        """Part points (n, 3) where the rays of fractional pixels (n, 2) meet a plane."""
        d = self.rays_at(rc)
        return self.origin + d * self.plane_range(coef, d)[:, None]


class Views:
    """The last few Views made, one per frame and placement: a view group's members are
    measured in the same frames, and each View keeps what was found in it (a hole's rim,
    fitted once for its diameter, position and edge distance).  A frame is known by
    identity; a cached View holds its frame, so no other frame can take its address while
    it is cached.  At most `size` Views (and their frames) are kept."""

    def __init__(self, size: int = 4):
        self.size = size
        self._views: OrderedDict[tuple[int, PartPlacement], View] = OrderedDict()

    def of(self, frame: RangeFrame, placement: PartPlacement) -> View:
        """The View of `frame` in `placement` (made now, or the one made before)."""
        key = (id(frame), placement)
        got = self._views.get(key)
        if got is not None and got.frame is frame:
            self._views.move_to_end(key)
            return got
        view = View(frame, placement)
        self._views[key] = view
        while len(self._views) > self.size:
            self._views.popitem(last=False)
        return view


@dataclass(frozen=True)
class Patch:
    """Pixels rows r0:r1, cols c0:c1 of a view, and the mask (r1-r0, c1-c0) of those in the
    region it was placed over."""

    name: str
    r0: int
    r1: int
    c0: int
    c1: int
    mask: NDArray[np.bool_]

    @property
    def slices(self) -> tuple[slice, slice]:
        return slice(self.r0, self.r1), slice(self.c0, self.c1)

    def take(self, image: np.ndarray) -> np.ndarray:
        """The patch's rectangle of an (H, W, ...) image."""
        return image[self.r0:self.r1, self.c0:self.c1]


def place_patch(view: View, name: str, corners: FloatArray, inside: Callable[[Patch], NDArray[np.bool_]] | None = None,
                margin_px: int = 1) -> Patch | None:
    """The patch covering part points `corners` (k, 3) mm; None when any corner falls
    outside the image.  inside: optional test patch -> (h, w) bool that refines the mask
    (of the points of the patch's pixels on the nominal surface, say: `nominal_points`)."""
    rc = view.pixel_of(corners)
    h, w = view.shape
    if not np.all(np.isfinite(rc)) or not view.geometry.contains(rc).all():
        return None
    r0 = max(int(np.floor(rc[:, 0].min())) - margin_px, 0)
    r1 = min(int(np.ceil(rc[:, 0].max())) + margin_px + 1, h)
    c0 = max(int(np.floor(rc[:, 1].min())) - margin_px, 0)
    c1 = min(int(np.ceil(rc[:, 1].max())) + margin_px + 1, w)
    if r1 - r0 < 2 or c1 - c0 < 2:
        return None
    mask = np.ones((r1 - r0, c1 - c0), dtype=bool)
    patch = Patch(name, r0, r1, c0, c1, mask)
    if inside is not None:
        mask &= inside(patch)
    return patch


def nominal_points(view: View, patch: Patch, z: float) -> FloatArray:
    """(h, w, 3) part points where the patch's pixel rays meet the plane z = `z` (mm)."""
    d = patch.take(view.dirs)
    return view.origin + d * view.plane_range((0.0, 0.0, z), d)[..., None]
