"""Finding a hole anywhere in a frame, when it is not where the pose says.

A rim fit looks for a hole's edge in a band round where the part's placement puts it; a
part that sits millimetres off (a first look before it is registered, a knock) shows the
hole elsewhere in the frame.  This finds it as the seed's Vision would: the pixels that
see through the face (no return, or a return deeper than the face by LOCATE_DEPTH_MM),
grouped into connected regions; the region of the hole's size (its area on the face
within AREA_RANGE of the nominal circle's) wholly inside the frame, nearest the hole's
nominal centre, is the hole; its centroid on the face plane is where it is.

    xy = find_hole(frame, placement, hole)     # (x, y) part mm, or None
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from ita.part.model import Hole
from ita.sensors.slra_frame import RangeFrame
from ita.vision.patches import View
from ita.workcell.model import PartPlacement

__all__ = ["AREA_RANGE", "find_hole"]

#: a region is the hole when its area on the face is within this share of the circle's
AREA_RANGE = (0.6, 1.5)
#: a pixel deeper than the face by more than this (mm) sees through it
DEPTH_MM = 1.0


def find_hole(frame: RangeFrame, placement: PartPlacement, hole: Hole) -> tuple[float, float] | None:
    """Where `frame` shows `hole` (part x, y mm in `placement`'s frame), None when no
    region of its size lies wholly inside the frame (module docstring)."""
    view = View(frame, placement)
    z = float(hole.center[2])
    dirs = view.dirs
    with np.errstate(invalid="ignore"):
        at_face = view.origin[:2] + dirs[..., :2] * view.plane_range((0.0, 0.0, z), dirs)[..., None]
        depth = view.points[..., 2]
        through = ~np.isfinite(depth) | (depth < z - DEPTH_MM)
    labels, n = ndimage.label(through)
    if n == 0:
        return None
    border = set(np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))) - {0}
    r = hole.diameter / 2.0
    d_row = np.diff(at_face, axis=0)[:, :-1]          # a pixel's sides on the face: the cross product
    d_col = np.diff(at_face, axis=1)[:-1]
    pixel_area = float(np.nanmedian(np.abs(d_row[..., 0] * d_col[..., 1] - d_row[..., 1] * d_col[..., 0])))
    if not np.isfinite(pixel_area) or pixel_area <= 0.0:
        return None
    circle = np.pi * r * r
    counts = np.bincount(labels.ravel(), minlength=n + 1)
    best: tuple[float, float] | None = None
    best_d = np.inf
    centre = np.asarray(hole.center[:2], dtype=float)
    for k in range(1, n + 1):
        if k in border or not AREA_RANGE[0] <= counts[k] * pixel_area / circle <= AREA_RANGE[1]:
            continue
        xy = at_face[labels == k]
        xy = xy[np.isfinite(xy).all(axis=1)]
        if len(xy) == 0:
            continue
        c = xy.mean(axis=0)
        d = float(np.hypot(*(c - centre)))
        if d < best_d:
            best, best_d = (float(c[0]), float(c[1])), d
    return best
